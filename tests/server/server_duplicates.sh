#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# One session, one server, one process per id (loopback, a DDS domain and
# session of its own, `timeout` around every process):
#   - two trainee bots given the same --id, started together: the server
#     listens to one only (one press in its report) and says so, never
#     reports a gap from their interleaved sequence numbers, and its
#     recording replays; the other bot learns from the server that its id
#     is taken and stops (status 2), the one heard carries on and is told
#     of the other. (A rule of who heard whom first, which this replaced,
#     let both carry on when they started within a second of each other.)
#   - a second ftm-server on a served session stops (status 3, naming the
#     first), the first goes on to its end (status 0), and --check on the
#     served session fails (status 3).
set -u
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}" "${FTM_SCRIPTS:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-dups.XXXXXX")
trap 'rm -rf "$dir"; kill $(jobs -p) 2>/dev/null' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.out "$dir"/*.log; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done
    exit 1
}
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
rate=${FTM_TEST_RATE:-200}
cd "$dir" || fail "no $dir"

# two bots, one id
common="--session dup-ids-$$ --domain $domain --config $FTM_CONFIG"
timeout 30 "$FTM_SERVER" $common --rate "$rate" --duration 5 --log ids.log --record ids.rec \
    --report ids.json >ids.out 2>&1 &
server=$!
sleep 1
timeout 30 "$FTM_BOT" $common --role trainee --id 11 --script "$FTM_SCRIPTS/trainee1.bot" \
    --duration 4 >bot1.out 2>&1 &
b1=$!
timeout 30 "$FTM_BOT" $common --role trainee --id 11 --script "$FTM_SCRIPTS/trainee2.bot" \
    --duration 4 >bot2.out 2>&1 &
b2=$!
wait $b1
rc1=$?
wait $b2
rc2=$?
# whichever the server heard first holds the id
if [ $rc1 -eq 0 ] && [ $rc2 -eq 2 ]; then held=bot1; ignored=bot2
elif [ $rc1 -eq 2 ] && [ $rc2 -eq 0 ]; then held=bot2; ignored=bot1
else fail "two bots with id 11: status $rc1 and $rc2, not 0 and 2 in some order"
fi
grep -q "participant id 11 is taken" $ignored.out || fail "$ignored does not say its id is taken"
! grep -q "participant id 11 is taken" $held.out || fail "$held, which the server hears, says its id is taken"
grep -q "another process joined as participant 11: the server ignores it" $held.out ||
    fail "$held was not told of the other"
wait $server || fail "the server failed"
grep -q "participant 11 (trainee .*): a second process uses this id" ids.log ||
    fail "no error about the second process using id 11"
! grep -q "missing before seq" ids.log || fail "the two bots' sequence numbers were taken as gaps"
# one trainee pressing once, not two probes merged (they made 9 touches)
grep -q '"touches":1,' ids.json || fail "the report's trainee 11 is not one probe's single press"
timeout 30 "$FTM_SERVER" --replay ids.rec >replay.out 2>&1 || fail "the recording does not replay"

# two servers, one session
common="--session dup-srv-$$ --domain $domain --config $FTM_CONFIG"
timeout 30 "$FTM_SERVER" $common --rate "$rate" --duration 4 --log first.log >first.out 2>&1 &
first=$!
sleep 1.5
timeout 30 "$FTM_SERVER" $common --check >check.out 2>&1
rc=$?
[ $rc -eq 3 ] || fail "--check on a served session: status $rc, not 3"
grep -q "^session *FAILS: already served by another ftm-server" check.out ||
    fail "--check does not say the session is served"
timeout 30 "$FTM_SERVER" $common --rate "$rate" --duration 4 --log second.log >second.out 2>&1
rc=$?
[ $rc -eq 3 ] || fail "a second server on the session: status $rc, not 3"
grep -q "is already served by another ftm-server .*: stopping this one" second.log ||
    fail "the second server does not say why it stopped"
wait $first || fail "the first server did not run to its end"
grep -q "another ftm-server .* joined session" first.log || fail "the first server did not notice"
exit 0
