#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/experiments.md's section on volumes (paper 4.2): runs
# `ftm experiment volume` on the synthetic head phantom and, when it is at
# hand, on a real head MRI (Colin27's brain, ch2bet.nii.gz, from Debian's
# mricron-data), keeping the tables and JSON under docs/bench/ and the
# pictures as docs/img/volume-phantom.png and docs/img/volume-ch2bet.png.
#   docs/bench/volume.sh [path/to/ftm] [path/to/ch2bet.nii.gz]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
mri=${2:-/usr/share/mricron/templates/ch2bet.nii.gz}
out=docs/bench
mkdir -p "$out" docs/img
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# run NAME ARGS...: the table to the terminal and volume-NAME.txt, the JSON
# (a second run) to volume-NAME.json, the picture to docs/img/volume-NAME.png
run() {
  local name=$1
  shift
  mkdir -p "$tmp/$name"
  "$ftm" experiment volume "$@" --out "$tmp/$name" |
    sed "s|$tmp/$name/volume.png|docs/img/volume-$name.png|" | tee "$out/volume-$name.txt"
  "$ftm" experiment volume "$@" --json > "$out/volume-$name.json"
  if [ -s "$tmp/$name/volume.png" ]; then
    cp "$tmp/$name/volume.png" "docs/img/volume-$name.png"
  fi
}

# the phantom: its skull is bright, as on CT, and fixes the lattice points in it
run phantom

# Colin27's brain, skull stripped (T1: bone is dark, the white matter the
# brightest tissue, so "hard by density" would fix the white matter, not
# bone): no hard tissue; the bottom face of the box is fixed instead, which
# holds the points at the brain stem, where the brain hangs from the skull.
if [ -f "$mri" ]; then
  run ch2bet --volume "$mri" --hard none --fix zmin
else
  echo "no $mri (Debian: apt-get install mricron-data): the MRI run is skipped" >&2
fi
echo "wrote $out/volume-*.txt $out/volume-*.json docs/img/volume-*.png"
