#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The adaptive depth at work (docs/server.md, docs/img/adaptive-depth.png):
# ftm-server at 1 kHz with --adaptive 1, trainee 11 pressing and holding,
# observer 13 stopped with SIGSTOP for 1.5 s; the server's control log (one
# CSV line per 100 ms: depth, step time, worst lag, tick rate) is plotted with
# gnuplot. Not a CTest test (timing on a shared machine); run by hand:
#   sh tests/server/depth_trace.sh build/release OUTDIR
set -eu
build=${1:?build dir}; out=${2:?output dir}
mkdir -p "$out"
here=$(cd "$(dirname "$0")" && pwd)
cfg=$here/../../deploy/cyclonedds-loopback.xml
session="trace-$$"; common="--session $session --domain $((220 + $$ % 12)) --config $cfg"
"$build/server/ftm-server" --scene default $common --rate 1000 --adaptive 1 --duration 16 \
    --control-log "$out/control.csv" --log "$out/server.log" >"$out/server.out" 2>/dev/null &
server=$!
until grep -q "session '$session'" "$out/server.log" 2>/dev/null; do sleep 0.05; done
t0=$(date +%s.%N)
"$build/bot/ftm-bot" --role trainee --script "$here/press-hold.bot" $common --id 11 \
    --duration 30 >"$out/bot11.out" 2>"$out/bot11.err" &
b11=$!
"$build/bot/ftm-bot" --role observer $common --id 13 --duration 30 \
    >"$out/bot13.out" 2>"$out/bot13.err" &
b13=$!
sleep 3.5
stop=$(echo "$(date +%s.%N) - $t0" | bc)
kill -STOP $b13; sleep 1.5; kill -CONT $b13
cont=$(echo "$(date +%s.%N) - $t0" | bc)
wait $server $b11 $b13
grep "info: depth" "$out/server.log" | grep -v "at the end" >"$out/depth-changes.txt" || true
cat "$out/server.out" "$out/bot11.out" "$out/bot13.out"
echo "observer stopped from ${stop} s to ${cont} s after the bots started"
gnuplot <<GP
set terminal pngcairo size 900,520 font "DejaVu Sans,10"
set output "$out/adaptive-depth.png"
set datafile separator ","
set key top right
set xlabel "server time [s]"
set ylabel "penetration depth n"
set y2label "worst participant lag [ticks]"
set yrange [0:10]
set y2range [0:*]
set ytics nomirror
set y2tics
set grid
set title "ftm-server 1 kHz, --adaptive 1: observer stopped (SIGSTOP) for 1.5 s"
plot "$out/control.csv" every ::1 using 1:3 with steps lw 2 title "depth", \
     "$out/control.csv" every ::1 using 1:6 axes x1y2 with lines lw 1 title "worst lag (ticks)", \
     "$out/control.csv" every ::1 using 1:(\$10/100) with lines lw 1 dt 2 title "tick rate / 100 Hz"
GP
echo "plot: $out/adaptive-depth.png"
