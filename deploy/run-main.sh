#!/usr/bin/env bash
# The main job, from a fresh clone: installs dependencies, builds, and runs a
# training session on loopback — ftm-server with two scripted trainees and an
# observer (deploy/run-session.sh) — printing what every participant ended
# on. Without a display (CI, a server) the session is headless; with one, an
# instructor window (ftm-client) joins it and it lasts 60 s.
#   deploy/run-main.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."

deploy/install-deps.sh >&2
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >&2
cmake --build build/release -j "$(nproc 2>/dev/null || echo 2)" >&2
exec deploy/run-session.sh build/release "${1:-6}"
