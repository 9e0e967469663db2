#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Session tests on loopback: ftm-server + ftm-bot processes.
#   basic: server + 2 trainees + 1 observer; every bot ends on the server's
#          final tick and hash, and each trainee's reaction-force profile
#          matches the same scripts run offline (ftm-server --offline: the
#          server's tick code without DDS, scripts played on the tick clock):
#          within 2 % of the peak force at 95 % of the ticks, 15 % at all.
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
. "$(cd "$(dirname "$0")" && pwd)/../wait_for.sh"
mode=${1:?mode}
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}" "${FTM_SCRIPTS:?}"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-net-$mode.XXXXXX")
trap 'rm -rf "$dir"' EXIT
# A domain of our own (the wire tests use 100..219) and a unique session.
domain=$(( 1 + $$ % 97 ))
session="net-$mode-$$"
# 200 Hz; a sanitizer build runs about 5x slower and ticks at 50 Hz (CMake sets it)
rate=${FTM_TEST_RATE:-200}
duration=4.5
[ "$mode" = kill ] && duration=5.5
[ "$mode" = rogue ] && duration=6
config=$FTM_CONFIG
[ "$mode" = lossy ] && config=${FTM_LOSSY_CONFIG:?}
common="--session $session --domain $domain --config $config"
# reaction profile vs offline, beyond the timing window, as fractions of the
# peak: for 95 % of the ticks in contact, and for every one (a scheduling
# stall of a loaded host, longer than the window, shows in a few ticks only).
# At a sanitizer build's 50 Hz a tick is 20 ms: trainee 12, pressing where
# trainee 11's dent reaches, feels the other's timing too, and one tick of
# 0.16..0.24 of the peak outside the window was seen on two busy cores while
# the 95th percentile stayed 0: the bound for every tick is 0.3 there.
PROFILE_TOL=${PROFILE_TOL:-0.02}
if [ "$rate" -ge 100 ]; then PROFILE_MAX_TOL=${PROFILE_MAX_TOL:-0.15}; else PROFILE_MAX_TOL=${PROFILE_MAX_TOL:-0.3}; fi
fail() { echo "FAIL: $*"; for f in "$dir"/*.out "$dir"/*.err; do echo "== $f"; tail -n 25 "$f"; done; exit 1; }

timeout 30 "$FTM_SERVER" --scene default $common --rate $rate --duration $duration \
    --log "$dir/server.log" >"$dir/server.out" 2>"$dir/server.err" &
server=$!
# wait (bounded) for the server to be up before the bots start
wait_for "$dir/server.log" "session '$session'" "server did not start" 100

# (the trainee to be killed runs without `timeout`, so that $b11 is the bot
# itself; its own --duration bounds it)
victim=timeout
[ "$mode" = kill ] && victim=
$victim ${victim:+30} "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee1.bot" $common --id 11 \
    --duration 15 --log "$dir/bot11.csv" >"$dir/bot11.out" 2>"$dir/bot11.err" &
b11=$!
timeout 30 "$FTM_BOT" --role trainee --script "$FTM_SCRIPTS/trainee2.bot" $common --id 12 \
    --duration 15 --log "$dir/bot12.csv" >"$dir/bot12.out" 2>"$dir/bot12.err" &
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
# Script time of tick 0 for a trainee, from its log: frame T reached the bot
# at time_s (bot clock = script clock) after latency_us; the HIP the server
# used for it was sampled about 0.9 ms before (half the 1 ms input period,
# the input's own latency, the step). Median over the frames.
script_t0() {
    awk -F, -v rate=$rate 'NR > 1 && $5 == 2 { printf "%.9f\n", $1 - $10 * 1e-6 - 0.0009 - $2 / rate }' \
        "$1" | sort -g | awk '{ v[NR] = $1 } END { if (NR) printf "%.6f", v[int((NR + 1) / 2)] }'
}
# The bot's reaction-force profile ($1, participant $2) against the offline
# run ($3). Online, the HIP at a tick is the newest sample the server had,
# so the bot's and the server's scheduling shift it in time (by tens of ms
# on a loaded machine); the force at tick T must therefore lie within the
# range the offline forces take over ticks T-k .. T+k (k: 50 ms of ticks,
# rounded up; 100 ms below 100 Hz, the sanitizer builds' rate, whose
# processes stall longer: at +-3 ticks of 50 Hz, 3 of trainee 11's 48 ticks
# in contact fell outside, 95th percentile 0.0208 > 0.02, on two busy
# cores), component by component. Ticks missing on one side count as zero
# force.
# Prints: ticks in contact offline, offline peak, largest pointwise
# difference, largest distance outside the window's range, that over peak.
if [ "$rate" -ge 100 ]; then win=$(( (rate + 19) / 20 )); else win=$(( (rate + 9) / 10 )); fi
profile_diff() {
    awk -F, -v id=$2 -v k=$win '
        FNR == 1 { file++; next }
        file == 1 && $5 == 2 { ox[$2] = $7; oy[$2] = $8; oz[$2] = $9; on[$2] = 1; if ($2 > hi) hi = $2 }
        file == 2 && $2 == id { fx[$1] = $4; fy[$1] = $5; fz[$1] = $6; off[$1] = 1; n++
                                m = sqrt($4^2 + $5^2 + $6^2); if (m > peak) peak = m; if ($1 > hi) hi = $1 }
        function out(v, lo, up) { return v < lo ? lo - v : (v > up ? v - up : 0) }
        END {
            for (t = 0; t <= hi; t++) {
                if (!(t in on) && !(t in off)) continue
                ax = (t in on) ? ox[t] : 0; ay = (t in on) ? oy[t] : 0; az = (t in on) ? oz[t] : 0
                bx = (t in off) ? fx[t] : 0; by = (t in off) ? fy[t] : 0; bz = (t in off) ? fz[t] : 0
                d = sqrt((ax-bx)^2 + (ay-by)^2 + (az-bz)^2); if (d > dmax) dmax = d
                lx = ux = bx; ly = uy = by; lz = uz = bz
                for (u = t - k; u <= t + k; u++) {
                    cx = (u in off) ? fx[u] : 0; cy = (u in off) ? fy[u] : 0; cz = (u in off) ? fz[u] : 0
                    if (cx < lx) lx = cx; if (cx > ux) ux = cx
                    if (cy < ly) ly = cy; if (cy > uy) uy = cy
                    if (cz < lz) lz = cz; if (cz > uz) uz = cz
                }
                e = sqrt(out(ax, lx, ux)^2 + out(ay, ly, uy)^2 + out(az, lz, uz)^2); if (e > emax) emax = e
                ne++; for (j = ne; j > 1 && es[j - 1] > e; j--) es[j] = es[j - 1]; es[j] = e
            }
            p95 = ne ? es[int(0.95 * ne + 0.999999)] : 0
            printf "%d %.6g %.6g %.6g %.4f %.4f\n", n, peak, dmax, emax, (peak > 0 ? emax / peak : 1),
                   (peak > 0 ? p95 / peak : 1)
        }' "$1" "$3"
}

case $mode in
basic)
    ticks=$(echo "$want" | awk '{ print $3 }')
    t11=$(script_t0 "$dir/bot11.csv"); t12=$(script_t0 "$dir/bot12.csv")
    [ -n "$t11" ] && [ -n "$t12" ] || fail "no synced frames in the trainees' logs"
    timeout 30 "$FTM_SERVER" --scene default --rate $rate --offline "$ticks" \
        --trainee "11:$t11:$FTM_SCRIPTS/trainee1.bot" --trainee "12:$t12:$FTM_SCRIPTS/trainee2.bot" \
        --reactions "$dir/offline.csv" >"$dir/offline.out" 2>"$dir/offline.err" ||
        fail "offline run failed"
    for b in 11 12; do
        set -- $(profile_diff "$dir/bot$b.csv" $b "$dir/offline.csv")
        echo "trainee $b: $1 ticks in contact offline, peak $2 N; largest difference at equal" \
             "ticks $3 N, outside the offline range of +-$win ticks: at most $4 N ($5 of the peak)," \
             "95th percentile $6 of the peak"
        [ "$1" -ge $((rate / 2)) ] || fail "trainee $b: only $1 ticks in contact offline (< 0.5 s)"
        awk -v r=$6 -v tol=$PROFILE_TOL 'BEGIN { exit !(r <= tol) }' ||
            fail "trainee $b: reaction profile outside the offline one by $6 of its peak at the 95th percentile (> $PROFILE_TOL)"
        awk -v r=$5 -v tol=$PROFILE_MAX_TOL 'BEGIN { exit !(r <= tol) }' ||
            fail "trainee $b: reaction profile outside the offline one by $5 of its peak (> $PROFILE_MAX_TOL)"
    done
    ;;
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
    for pat in \
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
        grep -q "$pat" "$dir/server.log" || fail "server log lacks: $pat"
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
