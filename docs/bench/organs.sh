#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/experiments.md's section on surface organs (paper 4.4):
# runs `ftm experiment organs` (the generated lung and stomach pressed by a
# probe, depths 1..12 and the whole organ), keeping the table and the JSON
# (a second run: its step times differ a little) under docs/bench/, the
# pictures as docs/img/organs.png and docs/img/organs_depth.png, and the
# organs with their scenes as docs/scenes/{lung,stomach}.obj and
# {lung,stomach}-surface.scene, and fills them with tetrahedra (make-volumes.sh).
#   docs/bench/organs.sh [path/to/ftm]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
out=docs/bench
mkdir -p "$out" docs/img docs/scenes
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$ftm" experiment organs --out "$tmp" --obj docs/scenes |
  sed "s|$tmp/|docs/img/|g" | tee "$out/organs.txt"
"$ftm" experiment organs --json > "$out/organs.json"
for png in organs organs_depth; do
  if [ -s "$tmp/$png.png" ]; then
    cp "$tmp/$png.png" "docs/img/$png.png"
  fi
done
docs/scenes/make-volumes.sh
# the scenes load and run
"$ftm" sim docs/scenes/stomach-surface.scene --steps 200 --quiet >/dev/null
"$ftm" sim docs/scenes/lung-surface.scene --steps 200 --quiet >/dev/null
"$ftm" sim docs/scenes/stomach.scene --steps 1 --press | grep "^press"
"$ftm" sim docs/scenes/lung.scene --steps 1 --press | grep "^press"
echo "wrote $out/organs.txt $out/organs.json docs/img/organs*.png docs/scenes/{lung,stomach}.{obj,node,ele} and the -surface scenes"
