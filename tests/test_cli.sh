#!/bin/sh
# End-to-end tests of the ftm command-line tool.
# Environment: FTM = path to the ftm binary, FTM_TEST_DATA = tests/data.
set -eu

: "${FTM:?set FTM to the ftm binary}"
: "${FTM_TEST_DATA:?set FTM_TEST_DATA to the tests/data directory}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_cli.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM

passed=0
failed=0

ok() {
    passed=$((passed + 1))
    echo "ok   $1"
}

not_ok() {
    failed=$((failed + 1))
    echo "FAIL $1" >&2
    if [ -s "$tmp/err" ]; then
        sed 's/^/     stderr: /' "$tmp/err" >&2
    fi
}

# run ARGS...: runs ftm, stdout in $tmp/out, stderr in $tmp/err, status in $rc.
run() {
    rc=0
    "$FTM" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?
}

# check NAME CONDITION...: passes if the condition command succeeds.
check() {
    name=$1
    shift
    if "$@"; then ok "$name"; else not_ok "$name"; fi
}

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
for name in default table3 membrane; do
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
for name in default table3 membrane; do
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
check "bench table3 unwritable JSON file fails" [ "$rc" -eq 1 ]
check "bench table3 names the file" grep -q 'no/such/dir/t3.json' "$tmp/err"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
