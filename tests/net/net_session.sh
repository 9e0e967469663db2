#!/bin/sh
# Session tests on loopback: ftm-server + ftm-bot processes.
#   basic: server + 2 trainees + 1 observer; every bot ends on the server's
#          final tick and hash.
#   late:  as basic, plus an observer joining 2 s late: it converges too.
#   kill:  one trainee is killed with SIGKILL mid-session: the other bots end
#          on the server's hash and the server logs that the trainee was lost.
#   lossy: as basic, with Cyclone dropping 5 % of all outgoing datagrams
#          (FTM_LOSSY_CONFIG, Internal/Test/XmitLossiness): every bot still
#          ends on the server's hash (reliable repair; a sequence gap would
#          make it resync from a keyframe).
#   rogue: as basic, plus a hostile participant (ftm-rogue, FTM_ROGUE) sending
#          malformed, oversized and forbidden messages mid-session: each is
#          rejected with its reason in the server's log, the forged frames
#          are ignored by the bots, and every bot ends on the server's hash.
# Every process runs under `timeout`; the test itself has a CTest TIMEOUT.
set -u
mode=${1:?mode}
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}" "${FTM_SCRIPTS:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-net-$mode.XXXXXX")
trap 'rm -rf "$dir"' EXIT
# A domain of our own (the wire tests use 100..219) and a unique session.
domain=$(( 1 + $$ % 97 ))
session="net-$mode-$$"
rate=200
duration=4.5
[ "$mode" = kill ] && duration=5.5
[ "$mode" = rogue ] && duration=6
config=$FTM_CONFIG
[ "$mode" = lossy ] && config=${FTM_LOSSY_CONFIG:?}
common="--session $session --domain $domain --config $config"
fail() { echo "FAIL: $*"; for f in "$dir"/*.out "$dir"/*.err; do echo "== $f"; tail -n 25 "$f"; done; exit 1; }

timeout 30 "$FTM_SERVER" --scene default $common --rate $rate --duration $duration \
    --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
server=$!
# wait (bounded) for the server to be up before the bots start
i=0
until grep -q "session '$session'" "$dir/server.log" 2>/dev/null; do
    i=$((i + 1)); [ $i -gt 100 ] && fail "server did not start"
    sleep 0.05
done

# (the trainee to be killed runs without `timeout`, so that $b11 is the bot
# itself; its own --duration bounds it)
victim=timeout
[ "$mode" = kill ] && victim=
$victim ${victim:+30} "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
    --duration 15 --log "$dir/bot11.csv" >"$dir/bot11.out" 2>"$dir/bot11.err" &
b11=$!
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee2.bot" $common --id 12 \
    --duration 15 >"$dir/bot12.out" 2>"$dir/bot12.err" &
b12=$!
timeout 30 "$FTM_BOT" --role observer $common --id 13 --duration 15 \
    >"$dir/bot13.out" 2>"$dir/bot13.err" &
b13=$!
bots="11 12 13"
b14=
if [ "$mode" = late ]; then
    timeout 30 "$FTM_BOT" --role observer --script "$FTM_SCRIPTS/observer-late.bot" $common \
        --id 14 --duration 15 >"$dir/bot14.out" 2>"$dir/bot14.err" &
    b14=$!
    bots="11 12 13 14"
fi
if [ "$mode" = rogue ]; then
    sleep 1.0
    timeout 20 "${FTM_ROGUE:?}" $common --id 91 --victim 11 >"$dir/rogue.out" 2>"$dir/rogue.err" ||
        fail "ftm-rogue failed"
fi
if [ "$mode" = kill ]; then
    sleep 1.5
    kill -KILL $b11 2>/dev/null || fail "trainee 11 was not running at 1.5 s"
    bots="12 13"
fi

wait $server; rc=$?
[ $rc -eq 0 ] || fail "server exited with $rc"
for b in $bots; do
    eval "pid=\$b$b"
    wait "$pid"; rc=$?
    [ $rc -eq 0 ] || fail "bot $b exited with $rc"
done
[ "$mode" = kill ] && wait $b11 2>/dev/null

want=$(sed -n 's/^ftm-server: \(final tick .*\)$/\1/p' "$dir/server.out")
[ -n "$want" ] || fail "no final line from the server"
for b in $bots; do
    got=$(sed -n "s/^ftm-bot $b: \\(final tick .*\\) synced\$/\\1/p" "$dir/bot$b.out")
    [ "$got" = "$want" ] || fail "bot $b: '$got', server: '$want'"
    grep -q "0 mismatches" "$dir/bot$b.err" || fail "bot $b saw hash mismatches"
done
grep -q "contact on triangle" "$dir/server.log" || fail "no probe contact on the server"
case $mode in
late)
    grep -q "replay: synced from keyframe" "$dir/bot14.err" || fail "late observer did not sync"
    ;;
kill)
    grep -q "participant 11 (trainee.* lost" "$dir/server.log" ||
        fail "server did not notice the killed trainee"
    ;;
rogue)
    # every hostile message was rejected with its reason ...
    n=$(grep -c "rejected message from participant 91 .*probe input: malformed" "$dir/server.log")
    [ "$n" -ge 2 ] || fail "garbage and truncated payloads: $n rejections logged, want 2"
    for want in \
        "from participant 91 .*probe input: .*not finite" \
        "from participant 91 .*probe input: payload of [0-9]* bytes exceeds" \
        "from participant 91 .*participant status: payload of [0-9]* bytes exceeds" \
        "from participant 91 .*probe input: .*memory budget" \
        "probe input topic: message from participant 91 .*session control" \
        "probe input from participant 91 rejected.*only trainees" \
        "session control from participant 91 rejected.*only the instructor" \
        "status from 91 names participant 11: ignored" \
        "session control from participant 92 rejected.*only the instructor" \
        "probe input from participant 92 rejected.*differs from the sender" \
        "probe sample from participant 92 rejected.*out of range"; do
        grep -q "$want" "$dir/server.log" || fail "server log lacks: $want"
    done
    # ... none of them took effect ...
    ! grep -q "paused at\|reset at" "$dir/server.log" || fail "a rogue command was obeyed"
    # ... and the replicas ignored the forged frames
    for b in $bots; do
        for k in "tick frame" keyframe; do
            grep -q "$k from participant 91 ignored" "$dir/bot$b.err" ||
                fail "bot $b did not ignore the forged $k"
        done
    done
    ;;
lossy)
    # the injection was on: the server's writer had to retransmit
    rexmit=$(sed -n 's/.*rexmit \([0-9]*\) bytes.*/\1/p' "$dir/server.log")
    [ "${rexmit:-0}" -gt 0 ] || fail "no retransmits: was loss injection active?"
    for b in $bots; do
        echo "bot $b: $(grep -o '[0-9]* gaps, [0-9]* resyncs' "$dir/bot$b.err")"
    done
    ;;
esac
echo "PASS $mode: $want; $(grep -o '[0-9]* ticks in.*' "$dir/server.log")"
