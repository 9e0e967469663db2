#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# End-to-end tests of `ftm fit`. Environment: FTM = the ftm binary,
# FIT_DIR = tests/fit (for small-cube.scene and two-tissue.scene).
set -eu

: "${FTM:?set FTM to the ftm binary}"
: "${FIT_DIR:?set FIT_DIR to the tests/fit directory}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_fit_cli.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM

passed=0
failed=0
ok() { passed=$((passed + 1)); echo "ok   $1"; }
not_ok() {
    failed=$((failed + 1))
    echo "FAIL $1" >&2
    if [ -s "$tmp/err" ]; then sed 's/^/     stderr: /' "$tmp/err" >&2; fi
}
run() { rc=0; "$FTM" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?; }
check() { name=$1; shift; if "$@"; then ok "$name"; else not_ok "$name"; fi; }

scene="$FIT_DIR/small-cube.scene"
quick="--iterations 6 --prerun 3 --nm-evals 8 --tolerance 1e-6"

# a quick fit, JSON
run fit "$scene" $quick --json --quiet --trace "$tmp/trace.csv"
check "fit exits 0" [ "$rc" -eq 0 ]
check "json has k, d, cases" grep -q '"k":.*"d":.*"cases":\[{"force":4,"avg_err_pct":' "$tmp/out"
check "three load cases by default (1, 2, 4 x the scene's load)" \
    grep -q '"force":16,' "$tmp/out"
check "both models and both optimisers" \
    sh -c "grep -q '\"model\":\"uniform\",\"method\":\"nelder-mead\"' '$tmp/out' &&
           grep -q '\"model\":\"classes\",\"method\":\"anneal\"' '$tmp/out'"
check "quiet: nothing on stderr" [ ! -s "$tmp/err" ]
check "trace written" grep -q '^uniform/anneal,6,' "$tmp/trace.csv"

# reproducible with the same seed (timings aside)
run fit "$scene" $quick --model uniform --forces 4,16 --json --quiet
cp "$tmp/out" "$tmp/first.json"
run fit "$scene" $quick --model uniform --forces 4,16 --json --quiet
strip_seconds() { sed 's/"seconds":[0-9.e+-]*//g' "$1"; }
strip_seconds "$tmp/first.json" >"$tmp/a"
strip_seconds "$tmp/out" >"$tmp/b"
check "same seed, same result" cmp -s "$tmp/a" "$tmp/b"

# text output with progress
run fit "$scene" $quick --model uniform --forces 2,4 --progress 2
check "text exits 0" [ "$rc" -eq 0 ]
check "text table" grep -q 'force \[N\]  avg err %' "$tmp/out"
check "progress lines on stderr" grep -q 'uniform/anneal *it *2' "$tmp/err"

# fixed-time mode fits d too
run fit "$scene" --mode fixed-time --time 0.01 --model uniform --iterations 4 --prerun 2 \
    --nm-evals 5 --json --quiet
check "fixed-time exits 0" [ "$rc" -eq 0 ]
check "fixed-time mode in json" grep -q '"mode":"fixed-time"' "$tmp/out"

# two tissues ([fem LABEL]): the reference of two materials, the springs
# weighted by their labels' moduli
run fit "$FIT_DIR/two-tissue.scene" $quick --model uniform --json --quiet
check "two tissues: exits 0" [ "$rc" -eq 0 ]
check "two tissues: the label's stiffness factor in json" \
    grep -q '"labels":\[{"label":9,"young":200000,"poisson":0.45,"stiffness_factor":0.333333333}\]' \
    "$tmp/out"
run fit "$FIT_DIR/two-tissue.scene" $quick --model uniform
check "two tissues: [material 9] in the text" grep -q '\[material 9\]  stiffness = 0.333333' "$tmp/out"

# errors
run fit
check "no target: exit 2" [ "$rc" -eq 2 ]
run fit "$scene" --stencil 18
check "--stencil with a scene: exit 2" [ "$rc" -eq 2 ]
run fit "$scene" --forces 1,x
check "bad --forces: exit 2" [ "$rc" -eq 2 ]
run fit "$scene" --bogus
check "unknown option: exit 2" [ "$rc" -eq 2 ]
run fit no-such.scene
check "missing scene: exit 2" [ "$rc" -eq 2 ]
run help fit
check "help fit" grep -q 'usage: ftm fit' "$tmp/out"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
