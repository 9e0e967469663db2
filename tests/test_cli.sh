#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# End-to-end tests of the ftm command-line tool.
# Environment: FTM = path to the ftm binary, FTM_TEST_DATA = tests/data.
set -eu

: "${FTM:?set FTM to the ftm binary}"
: "${FTM_TEST_DATA:?set FTM_TEST_DATA to the tests/data directory}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_cli.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM

# run, check, check_summary
. "$(cd "$(dirname "$0")" && pwd)/check.sh"

# same A B / differ A B: both non-empty and equal / different.
same() { [ -n "$1" ] && [ "$1" = "$2" ]; }
differ() { [ -n "$1" ] && [ -n "$2" ] && [ "$1" != "$2" ]; }

hash_of() {
    sed -n 's/^hash \([0-9a-f]\{16\}\)$/\1/p' "$1"
}

# --- the front end --------------------------------------------------------

run --version
check "--version prints the version" grep -q '^ftm [0-9][0-9.]*$' "$tmp/out"

run help
check "help exits 0 and lists sim" [ "$rc" -eq 0 ]
check "help lists the built-in scenes" grep -q 'default' "$tmp/out"

run
check "no command exits 2" [ "$rc" -eq 2 ]

run frobnicate
check "unknown command exits 2" [ "$rc" -eq 2 ]
check "unknown command is named" grep -q "frobnicate" "$tmp/err"

run sim --help
check "sim --help exits 0" [ "$rc" -eq 0 ]
check "sim --help shows usage" grep -q 'usage: ftm sim' "$tmp/out"

# --- ftm sim: the default scene, determinism --------------------------------

run sim
check "sim (default scene) exits 0" [ "$rc" -eq 0 ]
check "sim prints a 16-digit hash" grep -Eq '^hash [0-9a-f]{16}$' "$tmp/out"
check "sim names the scene" grep -q '^scene  *default$' "$tmp/out"
check "sim reports the reaction of the probe group" grep -q '^reaction  *group 0' "$tmp/out"
first=$(hash_of "$tmp/out")

run sim default
second=$(hash_of "$tmp/out")
check "two runs give the same hash" same "$first" "$second"

run sim --quiet
check "--quiet prints only the hash" [ "$(cat "$tmp/out")" = "hash $first" ]

run sim --json
check "--json exits 0" [ "$rc" -eq 0 ]
check "--json has the same hash" grep -q "\"hash\": \"$first\"" "$tmp/out"
check "--json has steps" grep -q '"steps": 2000' "$tmp/out"
check "--json is one line" [ "$(wc -l <"$tmp/out")" -eq 1 ]
for key in nodes max_displacement wall_s; do
    check "--json has $key" grep -q "\"$key\": " "$tmp/out"
done

run sim default --steps 100 --quiet
short=$(hash_of "$tmp/out")
check "--steps changes the run" differ "$short" "$first"

# The built-ins must run stably: no step rolled back by the stability guard.
for name in default table3 membrane head palpation; do
    run sim "$name"
    check "$name runs without guard events" grep -q '^guard  *0 events' "$tmp/out"
done

# --- CSV output --------------------------------------------------------------

run sim table3 --steps 50 --csv "$tmp/table3.csv"
check "table3 with --csv exits 0" [ "$rc" -eq 0 ]
check "CSV has nodes + 1 lines" [ "$(wc -l <"$tmp/table3.csv")" -eq 2501 ]
check "CSV header" [ "$(head -n 1 "$tmp/table3.csv")" = "node,x,y,z,ux,uy,uz" ]
check "CSV rows are in input order" [ "$(sed -n '2p' "$tmp/table3.csv" | cut -d, -f1)" = 0 ]

run sim membrane --steps 30 --csv - --quiet
check "--csv - writes CSV to stdout" [ "$(head -n 1 "$tmp/out")" = "node,x,y,z,ux,uy,uz" ]
check "--csv - writes nodes + 1 lines" [ "$(wc -l <"$tmp/out")" -eq 901 ]
check "--csv - moves the summary to stderr" grep -Eq '^hash [0-9a-f]{16}$' "$tmp/err"

for order in colored bfs jacobi; do
    run sim table3 --steps 40 --order "$order" --depth 5 --quiet
    check "--order $order runs" [ "$rc" -eq 0 ]
done

# --- scene files -------------------------------------------------------------

for scene in "$FTM_TEST_DATA"/scenes/*.scene; do
    run sim "$scene" --quiet
    check "runs $(basename "$scene")" [ "$rc" -eq 0 ]
done

# The documented copies of the built-ins must stay identical to them.
docs="$FTM_TEST_DATA/../../docs/scenes"
for name in default table3 membrane head palpation; do
    if [ -f "$docs/$name.scene" ]; then
        run sim "$name" --steps 300 --quiet
        builtin_hash=$(hash_of "$tmp/out")
        run sim "$docs/$name.scene" --steps 300 --quiet
        check "docs/scenes/$name.scene matches the built-in" \
            same "$builtin_hash" "$(hash_of "$tmp/out")"
    fi
done

# --- errors ------------------------------------------------------------------

cat >"$tmp/bad.scene" <<'EOF'
[mesh]
generator = lattice2d
nx = many
EOF
run sim "$tmp/bad.scene"
check "bad scene exits 2" [ "$rc" -eq 2 ]
check "bad scene error names file and line" grep -q 'bad.scene:3:' "$tmp/err"

run sim "$tmp/missing.scene"
check "missing scene file exits 2" [ "$rc" -eq 2 ]
check "missing scene file is named" grep -q 'missing.scene' "$tmp/err"

run sim no_such_builtin
check "unknown scene name exits 2" [ "$rc" -eq 2 ]
check "unknown scene name is named" grep -q 'no_such_builtin' "$tmp/err"

run sim --steps many
check "bad --steps exits 2" [ "$rc" -eq 2 ]
run sim --order random
check "bad --order exits 2" [ "$rc" -eq 2 ]
run sim --bogus
check "unknown option exits 2" [ "$rc" -eq 2 ]
run sim default table3
check "two scenes exit 2" [ "$rc" -eq 2 ]
run sim default --csv "$tmp/no/such/dir/out.csv"
check "unwritable CSV exits 2" [ "$rc" -eq 2 ]

# A time step far above the stability limit with no room to substep.
cat >"$tmp/unstable.scene" <<'EOF'
[mesh]
generator = lattice2d
nx = 6
ny = 6
spacing = 1
fixed_faces = all
[material]
mass = 1
stiffness = 100
[sim]
time_step = 1
guard = on
max_substeps = 1
steps = 50
[load]
node = 14
value = 0 -1 0
EOF
run sim "$tmp/unstable.scene"
check "diverging run exits 3" [ "$rc" -eq 3 ]
check "diverging run explains" grep -q 'diverged' "$tmp/err"
check "critical time step warning" grep -q 'warning' "$tmp/err"

# The Table 3 benchmark's output (its figures are timings: only their shape is
# checked here). One run, a few steps per figure: the table, and the same run's
# JSON in a file.
run bench table3 --steps 55 --eq-steps 100 --json-file "$tmp/t3.json"
check "bench table3 exits 0" [ "$rc" -eq 0 ]
check "bench table3 prints the depth 20 row with Eq. 9's count" \
    grep -Eq '^ +20 +1261 +1261 \|' "$tmp/out"
check "bench table3 JSON has 8 rows" \
    [ "$(grep -o '"depth":[0-9]*,"nodes"' "$tmp/t3.json" | wc -l)" -eq 8 ]
check "bench table3 JSON rows have search and step times" \
    grep -q '"depth":20,"nodes":1261,"paper_nodes":1261,"search_us":[0-9.]*,"step_us":[0-9.]*' \
    "$tmp/t3.json"
run bench table3 --steps 5
check "bench table3 rejects too few steps" [ "$rc" -eq 2 ]
check "bench table3 names the bad option" grep -q -- '--steps' "$tmp/err"
run bench table3 --json-file "$tmp/no/such/dir/t3.json"
check "bench table3 unwritable JSON file exits 2" [ "$rc" -eq 2 ]
check "bench table3 names the file and the reason" \
    grep -q 'no/such/dir/t3.json: cannot write: .' "$tmp/err"

# --- scene text: byte order mark, numbers ------------------------------------

# A UTF-8 byte order mark starting a scene file (as Windows editors write)
# is skipped: the same run as without it.
scene="$FTM_TEST_DATA/scenes/cube_press.scene"
printf '\357\273\277' >"$tmp/bom.scene"
cat "$scene" >>"$tmp/bom.scene"
run sim "$scene" --steps 50 --quiet
plain=$(hash_of "$tmp/out")
run sim "$tmp/bom.scene" --steps 50 --quiet
check "a scene starting with a byte order mark runs" [ "$rc" -eq 0 ]
check "the byte order mark changes nothing" same "$plain" "$(hash_of "$tmp/out")"

# Numbers are decimal: hexadecimal is refused, however strtod would read it;
# a long but valid number is read whole.
lattice_scene() { # SPACING FILE
    printf '[mesh]\ngenerator = lattice2d\nnx = 6\nny = 6\nspacing = %s\n' "$1" >"$2"
    printf '[material]\nmass = 0.001\nstiffness = 10\n' >>"$2"
}
lattice_scene 0x1p-7 "$tmp/hex.scene"
run sim "$tmp/hex.scene"
check "a hexadecimal number in a scene exits 2" [ "$rc" -eq 2 ]
check "the hexadecimal number is named with its line" grep -q 'hex.scene:5:.*0x1p-7' "$tmp/err"
zeros=0000000000000000000000000000000000000000000000000000000000000000000000000000
lattice_scene 0.01 "$tmp/short.scene"
lattice_scene "${zeros}${zeros}0.01" "$tmp/long.scene"
run sim "$tmp/short.scene" --steps 10 --quiet
short=$(hash_of "$tmp/out")
run sim "$tmp/long.scene" --steps 10 --quiet
check "a 156-character number in a scene is read" [ "$rc" -eq 0 ]
check "it is read as the short number" same "$short" "$(hash_of "$tmp/out")"

# --- outputs that cannot be written ------------------------------------------

# /dev/full takes the open and fails every write (ENOSPC): each output must
# be checked, named with the reason, and end in exit status 2.
run sim --csv /dev/full
check "sim --csv /dev/full exits 2" [ "$rc" -eq 2 ]
check "sim names the file and the reason" grep -q '^ftm sim: /dev/full: cannot write: .' "$tmp/err"
check "sim still prints the summary" grep -Eq '^hash [0-9a-f]{16}$' "$tmp/out"

rc=0
"$FTM" sim --quiet >/dev/full 2>"$tmp/err" || rc=$?
check "sim with standard output on /dev/full exits 2" [ "$rc" -eq 2 ]
check "the failed standard output is reported" grep -q 'standard output: cannot write: .' "$tmp/err"

run stability --quick --csv /dev/full
check "stability --csv /dev/full exits 2" [ "$rc" -eq 2 ]
check "stability names the file and the reason" \
    grep -q '^ftm stability: /dev/full: cannot write: .' "$tmp/err"

run experiment depth --quick --csv-dir "$tmp/no/such/dir"
check "experiment with a missing --csv-dir exits 2" [ "$rc" -eq 2 ]
check "experiment names the file and the reason" \
    grep -q 'no/such/dir/depth_change.csv: cannot write: .' "$tmp/err"
mkdir "$tmp/csv"
ln -s /dev/full "$tmp/csv/depth_profiles.csv"
run experiment depth --quick --csv-dir "$tmp/csv"
check "experiment with a CSV file on /dev/full exits 2" [ "$rc" -eq 2 ]
check "experiment names the failed CSV file" \
    grep -q 'csv/depth_profiles.csv: cannot write: .' "$tmp/err"
check "experiment writes the other CSV file" [ -s "$tmp/csv/depth_change.csv" ]

run bench table3 --steps 55 --eq-steps 100 --json-file /dev/full
check "bench table3 --json-file /dev/full exits 2" [ "$rc" -eq 2 ]
check "bench table3 names the file and the reason" \
    grep -q '^ftm bench table3: /dev/full: cannot write: .' "$tmp/err"

# --- option values -----------------------------------------------------------

run stability --csv
check "stability --csv without a file exits 2" [ "$rc" -eq 2 ]
check "stability says --csv needs a value" grep -q -- '--csv needs a value' "$tmp/err"
run bench table3 --json-file
check "bench table3 --json-file without a file exits 2" [ "$rc" -eq 2 ]
check "bench table3 says --json-file needs a value" grep -q -- '--json-file needs a value' "$tmp/err"
run bench table3 --steps 100x
check "bench table3 refuses --steps with junk" [ "$rc" -eq 2 ]

if "$FTM" bench --help | grep -q '^  net '; then
    run bench net --rate 0
    check "bench net --rate 0 exits 2" [ "$rc" -eq 2 ]
    check "bench net states the accepted --rate range" \
        grep -q -- '--rate must be above 0 and at most 10000' "$tmp/err"
    run bench net --bots 4294967297 # wrapped to 1 when cut to int
    check "bench net refuses --bots beyond int" grep -q -- '--bots must be in 1\.\.' "$tmp/err"
    run bench tick --trainees 0
    check "bench tick --trainees 0 exits 2" [ "$rc" -eq 2 ]
    check "bench tick states the accepted --trainees" grep -q -- '--trainees must be a list of 1\.\.16' "$tmp/err"
    run bench tick --scenes no-such-scene
    check "bench tick names a scene it cannot open" grep -q "scene 'no-such-scene'" "$tmp/err"
    run bench tick --duration
    check "bench tick says --duration needs a value" grep -q -- '--duration needs a value' "$tmp/err"
fi

# ftm fem and ftm fit (built with the FEM library only)
if "$FTM" help | grep -q '^  fit '; then
    printf '%s\n' '[mesh]' 'generator = lattice3d' 'nx = 3' 'ny = 3' 'nz = 3' 'spacing = 0.05' \
        'fixed_faces = zmin' '[material]' 'mass = 0.001' 'damping = 0.5' 'stiffness = 5000' \
        '[fem]' 'young = 0.6e6' 'poisson = 0.45' '[load]' 'node = 22' 'value = 0 0 -1' \
        >"$tmp/fem.scene"
    run fem "$tmp/fem.scene" --csv /dev/full
    check "fem --csv /dev/full exits 2" [ "$rc" -eq 2 ]
    check "fem names the file and the reason" grep -q '^ftm fem: /dev/full: cannot write: .' "$tmp/err"

    # [fem LABEL]: two unit hexahedra in physical groups 5 and 9, E 1e4 and
    # 4e4 Pa, nu 0, clamped at x = 0, 100 N on the x = 2 end: two springs in
    # series, u = 100 (1/1e4 + 1/4e4) = 0.0125 m (one material: 0.02 m)
    printf '%s\n' '$MeshFormat' '4.1 0 8' '$EndMeshFormat' '$Entities' '0 0 0 2' \
        '1 0 0 0 1 1 1 1 5 0' '2 1 0 0 2 1 1 1 9 0' '$EndEntities' '$Nodes' '1 12 1 12' \
        '3 1 0 12' 1 2 3 4 5 6 7 8 9 10 11 12 '0 0 0' '1 0 0' '2 0 0' '0 1 0' '1 1 0' \
        '2 1 0' '0 0 1' '1 0 1' '2 0 1' '0 1 1' '1 1 1' '2 1 1' '$EndNodes' '$Elements' \
        '2 2 1 2' '3 1 5 1' '1 1 2 5 4 7 8 11 10' '3 2 5 1' '2 2 3 6 5 8 9 12 11' \
        '$EndElements' >"$tmp/bar.msh"
    printf '%s\n' '[mesh]' "file = $tmp/bar.msh" 'fixed_box = -0.1 -0.1 -0.1 0.1 1.1 1.1' \
        '[material]' 'mass = 0.01' 'stiffness = 100' '[sim]' 'forces = linear-fem' \
        '[fem]' 'young = 1e4' 'poisson = 0' \
        '[load]' 'node = nearest 2 0 0' 'value = 25 0 0' '[load]' 'node = nearest 2 1 0' \
        'value = 25 0 0' '[load]' 'node = nearest 2 0 1' 'value = 25 0 0' \
        '[load]' 'node = nearest 2 1 1' 'value = 25 0 0' >"$tmp/bar1.scene"
    cp "$tmp/bar1.scene" "$tmp/bar2.scene"
    printf '%s\n' '[fem 9]' 'young = 4e4' 'poisson = 0' >>"$tmp/bar2.scene"
    run fem "$tmp/bar1.scene"
    check "fem: one material, 0.02 m" grep -q '^max |u|      0.02 m' "$tmp/out"
    run fem "$tmp/bar2.scene"
    check "fem honours [fem 9]: two in series, 0.0125 m" grep -q '^max |u|      0.0125 m' "$tmp/out"
    check "fem lists label 9's material" grep -q '^label 9      E = 40000 Pa, nu = 0' "$tmp/out"

    quick="--iterations 4 --prerun 2 --nm-evals 0 --tolerance 1e-5 --model uniform --forces 1"
    run fit "$tmp/fem.scene" $quick --quiet --trace /dev/full
    check "fit --trace /dev/full exits 2" [ "$rc" -eq 2 ]
    check "fit names the trace file and the reason" \
        grep -q '^ftm fit: /dev/full: cannot write: .' "$tmp/err"

    for seed in -1 99999999999999999999999 ' 7' 7x; do
        run fit "$tmp/fem.scene" $quick --quiet --seed "$seed"
        check "fit --seed '$seed' exits 2" [ "$rc" -eq 2 ]
        check "fit --seed '$seed' states the range" \
            grep -q -- '--seed must be an integer in 0..18446744073709551615' "$tmp/err"
    done
    run fit "$tmp/fem.scene" $quick --quiet --seed 18446744073709551615
    check "fit takes the largest seed" [ "$rc" -eq 0 ]
fi

check_summary
