#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Where CalculiX is installed: the stored decks (and the generated meshes)
# are what ccx_deck writes now, and ccx run on them gives the stored results
# (to 1e-5 of the largest value: ccx's solvers may round differently on
# another CPU).
# Exit 77 (skipped) without ccx. Environment: BUILD (the build directory),
# CCX_COMPARE.
set -eu
: "${BUILD:?set BUILD to the build directory}"
: "${CCX_COMPARE:?set CCX_COMPARE to the ccx_compare binary}"
command -v ccx >/dev/null 2>&1 || { echo "ccx not installed (calculix-ccx): skipped"; exit 77; }
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_ccx_rerun.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM
"$here/make_refs.sh" "$BUILD" "$tmp" >/dev/null
# the generated meshes are inputs: ccx_deck still writes them as stored
deck="$BUILD/tests/calculix/ccx_deck"
box="0.01 0.01 0.01"
incl="--label-box 0.03 0.01 0.01 0.05 0.03 0.03"
"$deck" --tetgen 2 2 2 $box "$tmp/tet1"
"$deck" --tetgen 5 5 5 $box "$tmp/tets"
"$deck" --tetgen 7 6 5 $box "$tmp/inclusion-tets" $incl
"$deck" --gmsh-hex 7 6 5 $box "$tmp/inclusion-hex.msh" $incl
bad=0
n=0
for mesh in tet1.node tet1.ele tets.node tets.ele inclusion-tets.node inclusion-tets.ele \
            inclusion-hex.msh; do
    n=$((n + 1))
    if cmp -s "$here/$mesh" "$tmp/$mesh"; then
        echo "ok   $mesh"
    else
        echo "FAIL $mesh: ccx_deck writes another mesh now" >&2
        bad=$((bad + 1))
    fi
done
for inp in "$here"/ref/*.inp; do
    name=$(basename "$inp" .inp)
    n=$((n + 1))
    if ! cmp -s "$inp" "$tmp/$name.inp"; then
        echo "FAIL $name.inp: ccx_deck writes another deck now" >&2
        diff "$inp" "$tmp/$name.inp" | head -5 >&2
        bad=$((bad + 1))
    elif ! "$CCX_COMPARE" dat "$tmp/$name.dat" "$here/ref/$name.dat" --tol 1e-5; then
        echo "FAIL $name.dat: ccx gives other results" >&2
        bad=$((bad + 1))
    else
        echo "ok   $name"
    fi
done
echo "$((n - bad)) passed, $bad failed"
[ "$bad" -eq 0 ] && [ "$n" -gt 0 ]
