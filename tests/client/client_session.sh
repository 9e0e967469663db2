#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-client's session thread without GL (test_session.c) against a real
# ftm-server on loopback (its own DDS domain and session):
#   idtaken: a bot presses under participant id 33; a trainee started
#       with the same id must write zero force and show no figures as its own
#   idback: the same, but the bot leaves after 3 s: the server hears the
#       trainee from then on and says so, and the trainee is told the id is
#       its own again (force back)
#   slow: while a bot presses (a frame every tick), a trainee whose replay
#       is 3x slower than the ticks keeps its status going: the server must
#       not declare it lost
#   pause: an instructor pauses for 3 s (server timeout 1 s): the banner
#       says paused, not silent
#   idwait: no ftm-server; test_session's stand-in server puts a force
#       under the trainee's id in every frame and confirms the id only after
#       5 s: no force, no probe input, no figures of its own until then
#   stall: a trainee pressing and holding is stopped (SIGSTOP) for 6 s,
#       past the DDS lease (2 s) and the server's status deadline, then
#       continued: the server's lease expired on its side while the same
#       server process went on; force and probe input must come back by
#       themselves (test_session checks the force; this script that the
#       server heard its contact again after the stall)
#   idforge: as idwait, but only a forger under the stand-in's id (another
#       process) confirms the id: never believed
#   softscene: the server runs `membrane` (0.019 N at a 7.5 mm press): an
#       instructor's log warns and its banner says the scene is far softer
#       than tissue (grey, not red), once synced
# Every process runs under timeout; no timing is asserted.
set -u
mode=${1:?mode}
. "$(cd "$(dirname "$0")" && pwd)/../wait_for.sh"
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_TEST_SESSION:?}" "${FTM_CONFIG:?}" "${FTM_DATA:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-client-session-$mode.XXXXXX")
server=
bot=
trap 'kill $server $bot 2>/dev/null; rm -rf "$dir"' EXIT
domain=$(( 220 + $$ % 10 ))   # as tests/client_gl (RUN_SERIAL); the session names differ
session="client-session-$mode-$$"
rate=${FTM_TEST_RATE:-500}
fail() { echo "FAIL: $*"; for f in "$dir"/*.log "$dir"/*.err; do [ -f "$f" ] && { echo "== $f"; tail -n 30 "$f"; }; done; exit 1; }
if [ "$mode" != idwait ] && [ "$mode" != idforge ]; then # (test_session serves the session itself)
    scene=default
    [ "$mode" = softscene ] && scene=membrane
    "$FTM_SERVER" --scene $scene --session "$session" --domain $domain --config "$FTM_CONFIG" \
        --rate "$rate" --duration 60 --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
    server=$!
    wait_for "$dir/server.log" "session '$session'" "server did not start"
fi
run() { # seconds id script
    timeout 60 "$FTM_TEST_SESSION" "$mode" $domain "$session" "$FTM_CONFIG" "$2" "$3" "$1" \
        >"$dir/test.out" 2>"$dir/test.err" || fail "test_session $mode exited with $?"
    # the join and sync lines name the tick it synced at (the join line
    # said the announcement's; "synced at" came with the first status, a
    # second later): the replay's keyframe, or the frames queued after it
    # (a bound of 3 s worth, for a slow sanitizer build on a loaded
    # machine; the tick of the first status was 500+ ticks on). And no
    # probe input went out before the server had the client's status.
    grep -q "joined session: .* syncing from a keyframe" "$dir/test.err" || fail "no join line"
    t1=$(sed -n 's/.*replay: synced from keyframe at tick \([0-9]*\).*/\1/p' "$dir/test.err" | head -n 1)
    t2=$(sed -n 's/.*] synced at tick \([0-9]*\).*/\1/p' "$dir/test.err" | head -n 1)
    [ -n "$t1" ] && [ -n "$t2" ] && [ "$t2" -ge "$t1" ] && [ "$t2" -le $((t1 + 3 * rate)) ] ||
        fail "synced at tick '$t2', the replay synced at '$t1'"
    # (not with the id taken: the bot's own early input has that id)
    [ "$mode" = idtaken ] || [ "$mode" = idback ] || [ "$mode" = idwait ] || [ "$mode" = idforge ] ||
        ! grep "probe input from participant $2 rejected" "$dir/server.log" ||
        fail "probe input went out before the server knew the client"
    cat "$dir/test.out"
}
press() { # a bot pressing under id $1 for ${2:-40} s: frames every tick
    timeout 60 "$FTM_BOT" --role trainee --script "$FTM_DATA/../client_gl/hold.bot" \
        --session "$session" --domain $domain --config "$FTM_CONFIG" --id $1 --duration ${2:-40} \
        >"$dir/bot.out" 2>"$dir/bot.err" &
    bot=$!
    wait_for "$dir/server.log" "participant $1 probe 0: contact" "the bot did not press" 600
}
case $mode in
idtaken)
    press 33
    run 5 33 "$FTM_DATA/side.bot"
    ;;
idback)
    press 35 4
    run 10 35 "$FTM_DATA/side.bot"
    grep -q "participant 35: the process that held the id is gone; the one ignored until now is heard" \
        "$dir/server.log" || fail "the server did not hand the id to the process it ignored"
    ;;
slow)
    press 34
    run 8 41 "$FTM_DATA/side.bot"
    ! grep "participant 41 .* lost" "$dir/server.log" || fail "the server declared the slow client lost"
    ;;
pause)
    run 7 42 -
    ;;
idwait)
    run 8 36 "$FTM_DATA/side.bot"
    ;;
idforge)
    run 6 37 "$FTM_DATA/side.bot"
    ;;
softscene)
    run 4 43 -
    grep -q "warn: scene 'membrane': .*far softer than tissue" "$dir/server.log" ||
        fail "the server did not warn of the soft scene"
    ;;
stall)
    # (not under timeout: the signals go to test_session itself; it ends by
    # itself after 16 s, and CTest's limit covers a hang)
    "$FTM_TEST_SESSION" stall $domain "$session" "$FTM_CONFIG" 38 "$FTM_DATA/hold-press.bot" 16 \
        >"$dir/test.out" 2>"$dir/test.err" &
    ts=$!
    wait_for "$dir/server.log" "participant 38 probe 0: contact" "the trainee did not press" 600
    kill -STOP $ts
    sleep 6
    kill -CONT $ts
    wait $ts || fail "test_session stall exited with $?"
    # the contact was released when the server declared the trainee lost;
    # the same trainee pressing again after the stall makes a new one
    [ "$(grep -c "participant 38 probe 0: contact" "$dir/server.log")" -ge 2 ] ||
        fail "the server never heard the trainee press again after the stall"
    cat "$dir/test.out"
    ;;
*) echo "unknown mode $mode"; exit 2 ;;
esac
