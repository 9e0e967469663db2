#!/bin/sh
# FTM against Bullet's soft body: `ftm bench peers` (docs/peers.md) once, its
# table and JSON under docs/bench/ and its plot, docs/img/peers.png.
#   docs/bench/peers.sh [FTM] [bench options]   (FTM: build/release/tools/ftm)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
ftm=${1:-build/release/tools/ftm}
[ $# -gt 0 ] && shift
"$ftm" bench peers --save "$here/peers" --plot "$here/../img/peers.png" "$@"
rm -f "$here/../img/peers.png.gp" "$here/../img/peers.png.dat"
