#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# `ftm fem` end to end against CalculiX's linear references: the
# displacements it writes with --csv, every node, to 1e-6 of the largest
# (ccx prints 7 digits); the inclusion-* cases with one material per label.
# Environment: FTM (the ftm binary), CCX_COMPARE.
set -eu
: "${FTM:?set FTM to the ftm binary}"
: "${CCX_COMPARE:?set CCX_COMPARE to the ccx_compare binary}"
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_ccx_fem_cli.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM
. "$here/../check.sh"
cd "$here" # the scenes name their mesh files relative to this directory

for c in hex1 tet1 block tets cube6-large elastin-cube-2mm inclusion-hex inclusion-tets; do
    run fem "$c.scene" --csv "$tmp/$c.csv"
    check "$c: ftm fem exits 0" [ "$rc" -eq 0 ]
    check "$c: displacements match CalculiX C3D8/C3D4 to 1e-6" \
        "$CCX_COMPARE" csv "$c.scene" "ref/$c.linear.dat" "$tmp/$c.csv" --tol 1e-6
done
check_summary
