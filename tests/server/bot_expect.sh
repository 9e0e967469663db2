#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-bot's expectations (docs/bot-script.md) on loopback: ftm-server with
# two trainees pressing. Trainee 11 (expect-hold.bot) states what must
# hold and exits 0, each expectation reported ok; trainee 12
# (expect-wrong.bot) has one that cannot hold and exits 4, the failure
# naming its file and line, the others ok. Both end on the server's hash:
# a failed expectation is not a sync failure.
# Every process runs under `timeout`; the test has a CTest TIMEOUT.
set -u
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}"
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-bot-expect.XXXXXX")
trap 'rm -rf "$dir"' EXIT
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
session="bot-expect-$$"
common="--session $session --domain $domain --config $FTM_CONFIG"
rate=${FTM_TEST_RATE:-200}
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.log "$dir"/*.out "$dir"/*.err; do [ -f "$f" ] && { echo "== $f"; tail -n 30 "$f"; }; done
    exit 1
}
timeout 60 "$FTM_SERVER" --scene default $common --rate "$rate" --duration 7.5 --log "$dir/server.log" \
    >"$dir/server.out" 2>"$dir/server.err" &
server=$!
wait_for "$dir/server.log" "session '$session'" "server did not start"
# the scripts' times count from each bot's start: both start together
timeout 60 "$FTM_BOT" --role trainee --script "$here/expect-hold.bot" $common --id 11 \
    --duration 30 >"$dir/bot11.out" 2>"$dir/bot11.err" &
b11=$!
timeout 60 "$FTM_BOT" --role trainee --script "$here/expect-wrong.bot" $common --id 12 \
    --duration 30 >"$dir/bot12.out" 2>"$dir/bot12.err" &
b12=$!
wait $server || fail "server exited with $?"
wait $b11; rc11=$?
wait $b12; rc12=$?
echo "== trainee 11 (exit $rc11)"; grep "expect" "$dir/bot11.err"
echo "== trainee 12 (exit $rc12)"; grep "expect" "$dir/bot12.err"
[ $rc11 -eq 0 ] || fail "trainee 11: exit $rc11, not 0"
[ $rc12 -eq 4 ] || fail "trainee 12: exit $rc12, not 4 (an expectation failed)"
[ "$(grep -c "^$here/expect-hold.bot:[0-9]*: expect .*: ok (" "$dir/bot11.err")" -eq 5 ] ||
    fail "trainee 11: not 5 expectations ok"
grep -q "0 of 5 expectations failed" "$dir/bot11.err" || fail "trainee 11: no summary"
grep -q "^$here/expect-wrong.bot:13: expect 2.1 4.1 force 50 100: FAILED: [0-9.]* N at t = " \
    "$dir/bot12.err" || fail "trainee 12: no failure naming line 13"
[ "$(grep -c "^$here/expect-wrong.bot:[0-9]*: expect .*: ok (" "$dir/bot12.err")" -eq 2 ] ||
    fail "trainee 12: its other 2 expectations not ok"
grep -q "1 of 3 expectations failed" "$dir/bot12.err" || fail "trainee 12: no summary"
want=$(sed -n 's/^ftm-server: \(final tick .*\)$/\1/p' "$dir/server.out")
[ -n "$want" ] || fail "no final line from the server"
for b in 11 12; do
    got=$(sed -n "s/^ftm-bot $b: \\(final tick .*\\) synced\$/\\1/p" "$dir/bot$b.out")
    [ "$got" = "$want" ] || fail "bot $b: '$got', server: '$want'"
done
echo "PASS bot expectations"
