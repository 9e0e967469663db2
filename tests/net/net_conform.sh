#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The protocol as a contract (docs/protocol.md, proto/): ftm-conform, a
# passive participant built from proto/ and Cyclone DDS alone, listens to a
# live session on loopback (ftm-server, trainees 11 and 12, instructor 13
# with one command of each kind: tests/net/conform-instructor.bot) from
# before the server starts until it leaves, and checks what it hears
# against the documented rules. It exits 1 naming each rule broken.
# Every process runs under `timeout`; the test itself has a CTest TIMEOUT.
set -u
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFORM:?}" "${FTM_CONFIG:?}" "${FTM_SCRIPTS:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-net-conform.XXXXXX")
trap 'rm -rf "$dir"' EXIT
# A domain no other test uses: 232, past the ranges of tests/net (1..97),
# tests/server (98..99, 220..231), tests/wire (100..219) and the client
# tests (220..229). Cyclone's default port mapping still fits it with the
# loopback configuration's 50 participant indices (ports up to 65511).
domain=232
session="net-conform-$$"
rate=${FTM_TEST_RATE:-200}
common="--session $session --domain $domain --config $FTM_CONFIG"
fail() { echo "FAIL: $*"; for f in "$dir"/*.out "$dir"/*.err "$dir"/*.log; do echo "== $f"; tail -n 25 "$f"; done; exit 1; }

# the listener first: it must see the keyframe of tick 0 and everyone's first status.
# Status intervals: 500 ms plus the sender's scheduling delay, up to 0.81 s seen
# with two busy cores at a load of 11 (--status-slack 0.4; the deadline is 2 s)
CYCLONEDDS_URI="file://$FTM_CONFIG" timeout 40 "$FTM_CONFORM" --domain $domain --session "$session" \
    --seconds 30 --rate $rate --from-start --participants 3 --status-slack 0.4 ${FTM_CONFORM_ARGS:-} \
    >"$dir/conform.out" 2>"$dir/conform.err" &
conform=$!
wait_for "$dir/conform.out" "listening" "ftm-conform did not start" 100
sleep 0.5
timeout 40 "$FTM_SERVER" --scene default $common --id 1 --rate $rate --duration 6.5 \
    --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
server=$!
wait_for "$dir/server.log" "session '$session'" "server did not start" 100
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
    --duration 15 >"$dir/bot11.out" 2>"$dir/bot11.err" &
b11=$!
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee2.bot" $common --id 12 \
    --duration 15 >"$dir/bot12.out" 2>"$dir/bot12.err" &
b12=$!
timeout 30 "$FTM_BOT" --role instructor --script "$here/conform-instructor.bot" $common --id 13 \
    --duration 15 >"$dir/bot13.out" 2>"$dir/bot13.err" &
b13=$!

wait $server || fail "server exited with $?"
wait $b11; wait $b12; wait $b13 # (their verdicts are other tests'; the 1e9 stiffness is refused: 4)
wait $conform; rc=$?
cat "$dir/conform.out"
[ $rc -eq 0 ] || fail "ftm-conform found the protocol broken (exit $rc)"
grep -q "pause" "$dir/server.log" || fail "the instructor's pause did not reach the server"
grep -q "^SKIP" "$dir/conform.out" && fail "a rule was not exercised"
echo "PASS conform: every documented rule held"
