#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The server's tick per training scene: `ftm bench tick` (docs/feel.md,
# "What a tick costs"), at each scene's own depth and with the adaptive
# depth, 1, 2 and 8 trainees; the tables and their JSON.
#   docs/bench/tick.sh [FTM]     (FTM: build/release/tools/ftm by default)
set -eu
ftm=${1:-build/release/tools/ftm}
here=$(cd "$(dirname "$0")" && pwd)
"$ftm" bench tick --json 2>"$here/tick.txt" >"$here/tick.json"
"$ftm" bench tick --adaptive --trainees 8 --json 2>>"$here/tick.txt" >"$here/tick-adaptive.json"
cat "$here/tick.txt"
