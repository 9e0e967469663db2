#!/bin/bash
# SPDX-License-Identifier: GPL-3.0-or-later
# deploy/run-session.sh, the main job's session (README), as an operator
# meets it:
#   - SECONDS that is not a whole number of seconds in 3..86400 is refused
#     with exit 2 before anything starts;
#   - a TMPDIR where no directory can be made is refused with exit 2;
#   - SIGTERM (and Ctrl-C, which the script turns into the same) stops every
#     process of the session: none is left running afterwards;
#   - (unsanitized builds with ftm-client) a DISPLAY that does not work is
#     reported and the session runs without the window and passes.
set -u
: "${FTM_BUILD:?}"
src=$(cd "$(dirname "$0")/../.." && pwd)
rs=$src/deploy/run-session.sh
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-runsession.XXXXXX")
trap 'rm -rf "$dir"' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.out; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done
    exit 1
}
export FTM_HEADLESS=1
for s in abc 1.5 0 2 -3 100000 ''; do
    [ -z "$s" ] && continue
    timeout 20 "$rs" "$FTM_BUILD" "$s" >"$dir/bad.out" 2>&1
    rc=$?
    [ $rc -eq 2 ] || fail "SECONDS '$s': exit $rc, not 2"
    grep -q "SECONDS must be a whole number of seconds, 3..86400: the trainees' presses take 2.4 s (got '$s')" "$dir/bad.out" ||
        fail "SECONDS '$s': no clear message"
done
TMPDIR=$dir/none timeout 20 "$rs" "$FTM_BUILD" 3 >"$dir/tmpdir.out" 2>&1
rc=$?
[ $rc -eq 2 ] || fail "unusable TMPDIR: exit $rc, not 2"
grep -q "cannot create a directory for the session's logs under $dir/none" "$dir/tmpdir.out" ||
    fail "unusable TMPDIR: no clear message"

# stopped 2 s into a 30 s session: everything gone within 10 s
# (its logs, kept when interrupted, under our directory)
TMPDIR=$dir setsid "$rs" "$FTM_BUILD" 30 >"$dir/term.out" 2>&1 &
pid=$!
i=0
until pgrep -f -- "--session main-$pid .*--id 13" >/dev/null; do
    i=$((i + 1)); [ $i -gt 200 ] && { kill -9 -- -$pid 2>/dev/null; fail "the session did not start"; }
    sleep 0.05
done
sleep 1
kill -TERM $pid
i=0
while kill -0 $pid 2>/dev/null; do
    i=$((i + 1)); [ $i -gt 100 ] && { kill -9 -- -$pid 2>/dev/null; fail "the script did not stop on SIGTERM"; }
    sleep 0.1
done
wait $pid
rc=$?
[ $rc -eq 143 ] || fail "SIGTERM: exit $rc, not 143"
grep -q "interrupted: stopping the session's processes (logs kept in $dir/ftm-session\." "$dir/term.out" ||
    fail "SIGTERM: no message, or the logs not kept"
i=0
while pgrep -f -- "--session main-$pid " >/dev/null; do
    i=$((i + 1))
    if [ $i -gt 100 ]; then
        left=$(pgrep -af -- "--session main-$pid ")
        pkill -9 -f -- "--session main-$pid "
        fail "processes left running after SIGTERM: $left"
    fi
    sleep 0.1
done

if [ -z "${FTM_SANITIZE:-}" ] && [ -x "$FTM_BUILD/client/ftm-client" ]; then
    DISPLAY=:0.77 FTM_HEADLESS=0 timeout 60 "$rs" "$FTM_BUILD" 3 >"$dir/display.out" 2>&1
    rc=$?
    [ $rc -eq 0 ] || fail "a session with a DISPLAY that does not work: exit $rc"
    grep -q "instructor window: could not open on ':0.77', the session ran without it" \
        "$dir/display.out" || fail "the unusable DISPLAY was not reported"
fi
echo "PASS run-session: bad SECONDS and TMPDIR refused, SIGTERM stops every process$(
    [ -f "$dir/display.out" ] && echo ', an unusable DISPLAY is reported')"
