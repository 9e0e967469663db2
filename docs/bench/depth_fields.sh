#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Draws docs/img/depth_fields.png: the displacement field of the table3 scene
# (50x50 lattice, force on the centre node) at equilibrium for penetration
# depths 2, 5, 10 and 20 — the region the force reaches, and what lies beyond
# it staying put.   docs/bench/depth_fields.sh [path/to/ftm]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for d in 2 5 10 20; do
  "$ftm" sim table3 --depth "$d" --steps 3000 --csv "$tmp/d$d.csv" --quiet >/dev/null
done
gnuplot <<GP
set terminal pngcairo size 1200,420 font "sans,10"
set output "docs/img/depth_fields.png"
set datafile separator ","
set multiplot layout 1,4 title "table3 scene at equilibrium, nodes at their deformed positions coloured by log10 |u| [m]: depth 2, 5, 10, 20"
set size ratio -1
unset key
set xrange [0:50]; set yrange [0:44]
set cbrange [-6:0]
set palette rgbformulae 33,13,10
set colorbox horizontal user origin 0.35,0.07 size 0.3,0.03
set xtics 10; set ytics 10
set xlabel "x [m] (deformed)"
set ylabel "y [m] (deformed)"
do for [d in "2 5 10 20"] {
  set title "depth ".d
  plot "$tmp/d".d.".csv" every ::1 using (\$2+\$5):(\$3+\$6):(log10(sqrt(\$5**2+\$6**2+\$7**2)+1e-6)) with points pt 7 ps 0.5 lc palette
}
unset multiplot
GP
echo "wrote docs/img/depth_fields.png"
