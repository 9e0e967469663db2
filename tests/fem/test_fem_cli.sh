#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# End-to-end tests of `ftm fem`. Environment: FTM = the ftm binary,
# FTM_TEST_DATA = tests/data, FTM_DOCS = docs/ (for docs/scenes/elastin-cube.scene).
set -eu

: "${FTM:?set FTM to the ftm binary}"
: "${FTM_TEST_DATA:?set FTM_TEST_DATA to the tests/data directory}"
: "${FTM_DOCS:?set FTM_DOCS to the docs directory}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_fem_cli.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM

# run, check, check_summary
. "$(cd "$(dirname "$0")" && pwd)/../check.sh"

# awk_true FILE PROGRAM: the awk program's exit status (0 = condition held)
awk_true() {
    awk -F, "$2" "$1"
}

# --- the example scene ----------------------------------------------------

cube="$FTM_DOCS/scenes/elastin-cube.scene"
run fem "$cube" --csv "$tmp/u.csv"
check "elastin-cube exits 0" [ "$rc" -eq 0 ]
check "summary counts nodes and hexahedra" grep -q '^mesh  *1000 nodes, 729 hexahedra, 0 tetrahedra$' "$tmp/out"
check "summary counts the dofs" grep -q '^dofs  *3000 (300 constrained, 2700 free)$' "$tmp/out"
check "summary has timings" grep -q '^time  *assemble .* factor .* solve ' "$tmp/out"
check "reaction balances the 10 N load" grep -Eq '^reaction  *[-0-9.e]+ [-0-9.e]+ 10(\.0*)? N' "$tmp/out"
check "max |u| is at a loaded node" grep -Eq '^max \|u\|  *0\.000651[0-9]* m at node 944 ' "$tmp/out"
check "CSV has a header and one row per node" [ "$(wc -l <"$tmp/u.csv")" -eq 1001 ]
check "CSV header" [ "$(head -1 "$tmp/u.csv")" = "node,x,y,z,ux,uy,uz" ]
check "clamped bottom does not move" awk_true "$tmp/u.csv" \
    'NR > 1 && $4 == 0 && ($5 != 0 || $6 != 0 || $7 != 0) { bad = 1 } END { exit bad }'
# symmetry: node 944 (4,4,9) and 955 (5,5,9) mirror each other in x and y
check "loaded nodes move symmetrically" awk_true "$tmp/u.csv" \
    '$1 == 944 { a = $5; b = $7 } $1 == 955 { c = $5; d = $7 }
     END { s = (a + c) / b; t = (b - d) / b; if (s < 0) s = -s; if (t < 0) t = -t;
           exit !(b < 0 && s < 1e-9 && t < 1e-9) }'

run fem "$cube" --json --factor simplicial
check "--json exits 0" [ "$rc" -eq 0 ]
check "--json is one object with the counts" grep -q '^{"scene":"elastin-cube","nodes":1000,"hexahedra":729,.*"supernodal":false' "$tmp/out"

run fem "$cube" --csv -
check "--csv - writes the CSV to stdout" [ "$(head -1 "$tmp/out")" = "node,x,y,z,ux,uy,uz" ]
check "--csv - sends the summary to stderr" grep -q '^dofs ' "$tmp/err"

# --- displacement loads: a prescribed rigid lift of the bottom --------------

cat >"$tmp/lift.scene" <<'SCENE'
[mesh]
generator = lattice3d
nx = 2
ny = 2
nz = 3
spacing = 0.01 0.02 0.005
[material]
mass = 0.001
stiffness = 10
[fem]
young = 1e5
poisson = 0.3
[load]
node = 0
kind = displacement
value = 0 0 0.001
[load]
node = 1
kind = displacement
value = 0 0 0.001
[load]
node = 2
kind = displacement
value = 0 0 0.001
[load]
node = 3
kind = displacement
value = 0 0 0.001
SCENE
run fem "$tmp/lift.scene" --csv "$tmp/lift.csv"
check "displacement loads exit 0" [ "$rc" -eq 0 ]
check "a rigid lift moves every node by 1 mm" awk_true "$tmp/lift.csv" \
    'function abs(x) { return x < 0 ? -x : x }
     NR > 1 && (abs($5) > 1e-15 || abs($6) > 1e-15 || abs($7 - 0.001) > 1e-15) { bad = 1 }
     END { exit bad }'

# --- a tetrahedral mesh file ----------------------------------------------

cat >"$tmp/tet.scene" <<SCENE
[mesh]
file = $FTM_TEST_DATA/tet.node
fixed_nodes = 0 1 2
[material]
mass = 0.001
stiffness = 10
[fem]
young = 1e4
poisson = 0.25
[load]
node = 3
value = 0.1 0 -1
SCENE
run fem "$tmp/tet.scene"
check "tetrahedra exit 0" [ "$rc" -eq 0 ]
check "tetrahedra are counted" grep -q '^mesh  *5 nodes, 0 hexahedra, 2 tetrahedra$' "$tmp/out"

# --- errors -----------------------------------------------------------------

run fem
check "missing scene exits 2" [ "$rc" -eq 2 ]
check "missing scene is explained" grep -q 'missing SCENE' "$tmp/err"

run fem --help
check "fem --help exits 0" [ "$rc" -eq 0 ]
check "fem --help shows usage" grep -q 'usage: ftm fem' "$tmp/out"

run fem "$cube" --factor cholesky
check "bad --factor exits 2" [ "$rc" -eq 2 ]

run fem "$tmp/none.scene"
check "missing file exits 2" [ "$rc" -eq 2 ]

run fem default
check "scene without [fem] exits 2" [ "$rc" -eq 2 ]
check "scene without [fem] is explained" grep -q 'no \[fem\] section' "$tmp/err"

sed 's/^poisson = 0.45/poisson = 0.5/' "$cube" >"$tmp/nu.scene"
run fem "$tmp/nu.scene"
check "poisson 0.5 exits 2" [ "$rc" -eq 2 ]
check "poisson 0.5 names the line" grep -q 'nu.scene:25: poisson must be > -1 and < 0.5, got 0.5' "$tmp/err"

sed 's/^fixed_faces = zmin/fixed_faces = none/' "$cube" >"$tmp/free.scene"
run fem "$tmp/free.scene"
check "unconstrained body exits 2" [ "$rc" -eq 2 ]
check "unconstrained body is explained" grep -q 'unconstrained body or mechanism' "$tmp/err"

cat >"$tmp/flat.scene" <<'SCENE'
[mesh]
generator = lattice2d
nx = 4
ny = 4
spacing = 1
fixed_faces = all
[material]
mass = 1
stiffness = 1
[fem]
young = 1
poisson = 0.3
SCENE
run fem "$tmp/flat.scene"
check "2D lattice exits 2" [ "$rc" -eq 2 ]
check "2D lattice is explained" grep -q 'no hexahedra or tetrahedra' "$tmp/err"

check_summary
