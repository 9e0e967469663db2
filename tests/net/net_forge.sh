#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# A process that passes itself off as the server (ftm-rogue --forge): it
# uses the server's participant id (a copied --id) and another id, claims
# role SERVER under both, and sends server statuses and control replies of
# its own making, while a real session runs on loopback:
#   - trainee 11 holds its id; a second trainee process with id 11 is
#     ignored by the server. The rogue confirms each process of id 11 as the
#     holder: the ignored one must never believe it (no "confirmed", no
#     probe input), and must stop with exit 2 (its id is taken);
#   - the rogue lists trainee 12's process as ignored: 12 must never
#     believe its id is taken, and ends on the server's hash;
#   - the rogue answers every command of instructor 15 "applied" at once:
#     the server refuses one of them, and the instructor must count the
#     server's answers only (2 applied, 1 refused, exit 4).
# Every process runs under `timeout`; the test itself has a CTest TIMEOUT.
set -u
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_ROGUE:?}" "${FTM_CONFIG:?}" "${FTM_SCRIPTS:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-net-forge.XXXXXX")
trap 'rm -rf "$dir"' EXIT
domain=$(( 1 + $$ % 97 ))
session="net-forge-$$"
rate=${FTM_TEST_RATE:-200}
common="--session $session --domain $domain --config $FTM_CONFIG"
fail() { echo "FAIL: $*"; for f in "$dir"/*.out "$dir"/*.err "$dir"/*.log; do echo "== $f"; tail -n 25 "$f"; done; exit 1; }

timeout 40 "$FTM_SERVER" --scene default $common --id 1 --rate $rate --duration 6 \
    --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
server=$!
wait_for "$dir/server.log" "session '$session'" "server did not start" 100
timeout 30 "$FTM_ROGUE" $common --id 1 --forge 6 --taken 11 --innocent 12 \
    >"$dir/rogue.out" 2>"$dir/rogue.err" &
rogue=$!
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
    --duration 15 >"$dir/bot11.out" 2>"$dir/bot11.err" &
b11=$!
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee2.bot" $common --id 12 \
    --duration 15 >"$dir/bot12.out" 2>"$dir/bot12.err" &
b12=$!
wait_for "$dir/bot11.err" "participant id 11 is confirmed" "trainee 11 was never confirmed"
# the second process with id 11, once the server holds the first
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
    --duration 15 >"$dir/taken.out" 2>"$dir/taken.err" &
taken=$!
timeout 30 "$FTM_BOT" --role instructor --script "$here/../server/control-instructor.bot" $common \
    --id 15 --duration 15 >"$dir/bot15.out" 2>"$dir/bot15.err" &
b15=$!

wait $server || fail "server exited with $?"
wait $rogue || fail "ftm-rogue exited with $?"
wait $taken; rc=$?
[ $rc -eq 2 ] || fail "the second process with id 11 exited with $rc, want 2 (id taken)"
for b in 11 12; do
    eval "pid=\$b$b"
    wait "$pid" || fail "bot $b exited with $?"
done
wait $b15; rc15=$?

# the rogue did forge all three (else the test proves nothing)
for pat in "server statuses confirming participant 11 for each of its 2 processes" \
    "server status ignoring participant 12" "an applied control reply"; do
    grep -q "forged $pat" "$dir/rogue.out" || fail "the rogue did not send: forged $pat"
done
# a taken id is never confirmed, whoever claims to be the server
! grep -q "participant id 11 is confirmed" "$dir/taken.err" ||
    fail "the ignored process with id 11 believed a forged confirmation"
grep -q "participant id 11 is taken" "$dir/taken.err" || fail "the ignored process was not told"
# an innocent trainee's id is not taken because a forger says so
! grep -q "participant id 12 is taken" "$dir/bot12.err" ||
    fail "trainee 12 believed a forged ignored list"
! grep -q "no longer confirms" "$dir/bot11.err" "$dir/bot12.err" ||
    fail "a holder lost its confirmation to a forged status"
# the instructor counts the server's answers only
[ $rc15 -eq 4 ] || fail "instructor exited with $rc15, want 4 (a command refused)"
grep -q "commands: 3 sent, 2 applied, 0 changed, 1 refused, 0 unanswered" "$dir/bot15.err" ||
    fail "the instructor counted a forged reply"
# the forgeries were seen and set aside as not the server's
grep -q "participant status from participant 1 .*ignored" "$dir/bot12.err" ||
    fail "trainee 12 did not report the forged statuses under the server's id"
want=$(sed -n 's/^ftm-server: \(final tick .*\)$/\1/p' "$dir/server.out")
for b in 11 12 15; do
    got=$(sed -n "s/^ftm-bot $b: \\(final tick .*\\) synced\$/\\1/p" "$dir/bot$b.out")
    [ "$got" = "$want" ] || fail "bot $b: '$got', server: '$want'"
done
echo "PASS forge: $(grep 'forge done' "$dir/rogue.out"); $(grep -o 'commands: .*' "$dir/bot15.err")"
