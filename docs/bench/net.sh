#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/bench-net.md: runs `ftm bench net` once (8 trainee bots at
# 1 kHz for 60 s on the 1k-node scene, the 100k-node scene, the adaptive
# phase under loss), keeps its table and JSON under docs/bench/, and draws
# docs/img/bench-net.png from its gnuplot data.
#   docs/bench/net.sh [path/to/ftm] [bench options, e.g. --bots 2]
#   docs/bench/net.sh --plot-only DIR   (redraw from a kept --plot DIR)
# Options after the ftm path go to the bench; with --bots N (N != 8) the
# results are written as docs/bench/net-Nbots.* instead.
set -euo pipefail
cd "$(dirname "$0")/../.."
out=docs/bench/net
img=docs/img/bench-net.png
if [ "${1:-}" = --plot-only ]; then
  plot=${2:?plot data directory}
else
  ftm=${1:-build/release/tools/ftm}
  shift || true
  args=("$@")
  for ((i = 0; i < ${#args[@]}; i++)); do
    if [ "${args[$i]}" = --bots ] && [ "${args[$((i + 1))]:-8}" != 8 ]; then
      out=docs/bench/net-${args[$((i + 1))]}bots
      img=docs/img/bench-net-${args[$((i + 1))]}bots.png
    fi
  done
  plot=$(mktemp -d); trap 'rm -rf "$plot"' EXIT
  # the table goes to standard error, the JSON to standard output
  "$ftm" bench net --plot "$plot" --json "$@" >"$out.json" 2> >(tee "$out.txt" >&2)
  wait
fi

gnuplot <<GP
set terminal pngcairo size 1500,900 font "sans,10"
set output "$img"
set multiplot layout 2,2
set grid

set title "server-to-bot latency, 1k-node scene (per second of the run)"
set xlabel "time [s]"
set ylabel "latency [us]"
set logscale y
set key top right
plot "$plot/latency.dat" using 1:2 with lines lw 2 lc rgb "#1f77b4" title "FTM tick frame p50", \
     "$plot/latency.dat" using 1:3 with lines lw 1 lc rgb "#1f77b4" dt 2 title "FTM tick frame p99", \
     "$plot/ddsperf.dat" using 1:2 with lines lw 2 lc rgb "#7f7f7f" title "ddsperf p50 (one way)", \
     "$plot/ddsperf.dat" using 1:3 with lines lw 1 lc rgb "#7f7f7f" dt 2 title "ddsperf p99"
unset logscale y

set title "bytes per tick: tick frames vs streaming moved nodes"
set xlabel ""
set ylabel "bytes per tick"
set logscale y
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.8 border -1
set yrange [100:1e6]
set key top left
plot "$plot/bytes.dat" using 2:xtic(1) lc rgb "#1f77b4" title "FTM: contacts and forces", \
     "" using 3 lc rgb "#ff7f0e" title "streaming every moved node"
unset logscale y
set yrange [*:*]
set style data lines

set key top right
set title "adaptive depth: loss injection on, one bot stopped twice"
set xlabel "time [s]"
set ylabel "penetration depth"
set yrange [0:*]
plot "$plot/adaptive-depth.dat" using 1:2 with steps lw 2 lc rgb "#d62728" title "depth (server)"

set title "the stopped bot's lag"
set ylabel "lag [ticks]"
set logscale y
set yrange [0.1:*]
plot "$plot/adaptive-lag.dat" using 1:2 with points pt 7 ps 0.2 lc rgb "#2ca02c" title "replay lag: frame latency + pickup, in ticks"
unset multiplot
GP
echo "wrote $out.txt $out.json $img" >&2
