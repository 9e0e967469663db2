# SPDX-License-Identifier: GPL-3.0-or-later
# shellcheck shell=sh
# Sourced by the command-line tests: a tally of named checks. Needs $tmp (a
# scratch directory the test made) and $FTM (the program run by `run`).
#   run ARGS...         runs $FTM: stdout in $tmp/out, stderr in $tmp/err,
#                       exit status in $rc
#   check NAME CMD...   passes if CMD succeeds; a failure shows $tmp/err
#   check_summary       prints the counts; fails if any check failed
#   json EXPR           a Python expression (it may span lines) over the JSON
#                       in $tmp/out (as d) is true (needs python3)
#   exit2_naming TEXT   the last run exited 2 and its stderr has TEXT
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

run() {
    rc=0
    "$FTM" "$@" >"$tmp/out" 2>"$tmp/err" || rc=$?
}

check() {
    name=$1
    shift
    if "$@"; then ok "$name"; else not_ok "$name"; fi
}

check_summary() {
    echo "$passed passed, $failed failed"
    [ "$failed" -eq 0 ]
}

json() {
    python3 -c 'import json, sys
d = json.load(open(sys.argv[1]))
sys.exit(0 if eval("(" + sys.argv[2] + ")") else 1)' "$tmp/out" "$1"
}

exit2_naming() { [ "$rc" -eq 2 ] && grep -q -- "$1" "$tmp/err"; }
