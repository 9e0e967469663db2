#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The main job, from a fresh clone: installs dependencies, builds, and runs a
# training session on loopback — ftm-server with two scripted trainees, a
# scripted instructor and an observer (deploy/run-session.sh) — printing
# what every participant ended on. Without a display (CI, a server;
# FTM_HEADLESS=1 forces it) the session is headless and lasts 6 s; with
# one, an instructor window (ftm-client) joins it and it lasts 60 s.
#   deploy/run-main.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
case ${1:-} in
  -h|--help) sed -n 's/^#   \(deploy\/run-main.sh .*\)$/usage: \1/p' "$0"; exit 0 ;;
  '') ;;
  *) [[ $1 =~ ^[1-9][0-9]{0,4}$ ]] && [ "$1" -ge 3 ] && [ "$1" -le 86400 ] || {
       echo "run-main: SECONDS must be a whole number of seconds, 3..86400: the trainees' presses take 2.4 s (got '$1')" >&2
       exit 2
     } ;;
esac

deploy/install-deps.sh >&2
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >&2
cmake --build build/release -j "$(nproc 2>/dev/null || echo 2)" >&2
# no SECONDS: run-session.sh's default, 6 s headless or 60 s with a window
exec deploy/run-session.sh build/release ${1:+"$1"}
