#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Regenerates the CalculiX references of tests/calculix (docs/calculix.md):
# writes each deck from its scene with ccx_deck, runs ccx (Debian package
# calculix-ccx) on it and keeps the deck (.inp) and ccx's printed results
# (.dat); ccx's other files are removed.
#
#   tests/calculix/make_refs.sh BUILD_DIR [OUT_DIR]
#
# BUILD_DIR: a CMake build of FTM (for BUILD_DIR/tests/calculix/ccx_deck).
# OUT_DIR: where to write (default tests/calculix/ref). The tetrahedral
# meshes are inputs, not regenerated here: ccx_deck --tetgen 2 2 2 0.01 0.01
# 0.01 tet1 and ccx_deck --tetgen 5 5 5 0.01 0.01 0.01 tets wrote them; the
# two-tissue meshes ccx_deck --gmsh-hex 7 6 5 0.01 0.01 0.01 inclusion-hex.msh
# --label-box 0.03 0.01 0.01 0.05 0.03 0.03 and ccx_deck --tetgen (the same
# arguments, OUTBASE inclusion-tets).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
[ $# -ge 1 ] || { echo "usage: $0 BUILD_DIR [OUT_DIR]" >&2; exit 2; }
deck=$(cd "$1" && pwd)/tests/calculix/ccx_deck
out=${2:-$here/ref}
[ -x "$deck" ] || { echo "make_refs: $deck not built" >&2; exit 2; }
command -v ccx >/dev/null || { echo "make_refs: ccx not found (apt-get install calculix-ccx)" >&2; exit 2; }
mkdir -p "$out"
out=$(cd "$out" && pwd)

# case model increments: one reference each
while read -r case model inc; do
  name=$case.$( [ "$model" = neo-hookean ] && echo neo || echo linear )
  (cd "$here" && "$deck" "$case.scene" "$out/$name.inp" --model "$model" --increments "$inc")
  (cd "$out" && ccx "$name" >"$name.log" 2>&1) || { echo "make_refs: ccx $name failed (see $out/$name.log)" >&2; exit 1; }
  grep -q 'total force' "$out/$name.dat" || { echo "make_refs: $name.dat has no reactions" >&2; exit 1; }
  rm -f "$out/$name.frd" "$out/$name.sta" "$out/$name.cvg" "$out/$name.12d" "$out/$name.log" \
        "$out/spooles.out"
  echo "make_refs: $name"
done <<'LIST'
hex1 neo-hookean 4
hex1 linear 1
tet1 neo-hookean 4
tet1 linear 1
block neo-hookean 10
block linear 1
tets neo-hookean 10
tets linear 1
cube6-large neo-hookean 20
cube6-large linear 1
elastin-cube-10mm neo-hookean 10
elastin-cube-2mm linear 1
inclusion-hex neo-hookean 10
inclusion-hex linear 1
inclusion-tets neo-hookean 10
inclusion-tets linear 1
LIST
