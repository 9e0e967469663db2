#!/bin/sh
# The step of every force model beside the springs' (issue 32, item 1):
# `ftm bench accuracy --speed` on the elastin cube, hexahedra and
# tetrahedra, full depth, alternating in one run; table and JSON under
# docs/bench/ (docs/benchmarks.md, "Element forces beside springs").
#   docs/bench/speed.sh [FTM]   (FTM: build/release/tools/ftm)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
ftm=${1:-build/release/tools/ftm}
"$ftm" bench accuracy --speed >"$here/speed.txt"
"$ftm" bench accuracy --speed --json >"$here/speed.json"
cat "$here/speed.txt"
