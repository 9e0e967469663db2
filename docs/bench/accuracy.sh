#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/accuracy.md: runs `ftm bench accuracy` once (both bodies),
# keeps its table, JSON and gnuplot data under docs/bench/, and draws
# docs/img/accuracy.png (error against time to equilibrium, Pareto fronts).
#   docs/bench/accuracy.sh [path/to/ftm] [bench options, e.g. --mesh cube]
#   docs/bench/accuracy.sh --plot-only    (redraw from docs/bench/accuracy.dat)
set -euo pipefail
cd "$(dirname "$0")/../.."
out=docs/bench/accuracy
if [ "${1:-}" != --plot-only ]; then
  ftm=${1:-build/release/tools/ftm}
  shift || true
  "$ftm" bench accuracy --save "$out" "$@"
fi

dat="$out.dat"
# one file per body and method (gnuplot reads them by name; a series with no
# rows is left out of the plot)
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
awk -v dir="$tmp" '!/^#/ && NF >= 10 { print > (dir "/" $1 "_" $2 ".dat") }' "$dat"
# columns: mesh method depth nodes h step_us steps time_s setup_s error
Y='($10<1e-9?1e-9:$10)'
series() { # body method style title [extra: labels offset]
  f="$tmp/$1_$2.dat"
  [ -s "$f" ] || return 0
  printf '"%s" using 8:%s %s title "%s", \\\n' "$f" "$Y" "$3" "$4"
  [ -n "${5:-}" ] && printf '"%s" using 8:%s:3 with labels offset %s notitle, \\\n' "$f" "$Y" "$5"
  return 0
}
panel() { # body title
  echo "set title \"$2\""
  echo "plot \\"
  series "$1" ft-springs "with linespoints lw 2 pt 7 lc rgb '#1f77b4'" "transmittal, springs (depth 1..full)" "-0.8,0.8 tc rgb '#1f77b4'"
  series "$1" ft-fem "with linespoints lw 2 pt 5 lc rgb '#d62728'" "transmittal, linear FEM forces (depth 1..full)" "1,-0.9 tc rgb '#d62728'"
  series "$1" ft-corot "with points ps 1.6 pt 9 lc rgb '#9467bd'" "transmittal, co-rotational FEM forces (full)"
  series "$1" explicit-springs "with points ps 1.6 pt 11 lc rgb '#2ca02c'" "explicit mass-spring, all nodes"
  series "$1" implicit-springs "with points ps 1.6 pt 13 lc rgb '#ff7f0e'" "backward Euler mass-spring (constant tangent)"
  series "$1" implicit-newton "with points ps 1.6 pt 12 lc rgb '#8c564b'" "backward Euler mass-spring (Newton)"
  series "$1" fem-cholmod "with points ps 2 pt 3 lc rgb 'black'" "linear FEM, prefactored CHOLMOD (error 0: drawn at 1e-9)"
  cat "$tmp/pareto-$1"_*.dat 2>/dev/null | sort -g -k8 >"$tmp/front-$1.dat" || true
  printf '"%s" using 8:%s with steps lw 8 lc rgb "#b0808080" title "Pareto front"\n' "$tmp/front-$1.dat" "$Y"
}
gnuplot <<GP
set terminal pngcairo size 1500,720 font "sans,10"
set output "docs/img/accuracy.png"
set multiplot layout 1,2
set logscale xy
set grid
# the key below the panels: inside, it hid the CHOLMOD points (drawn at 1e-9)
set key below maxrows 4 font "sans,8"
set bmargin 11
set xlabel "time to equilibrium per load [s]  (steps x median step; set-up not included)"
set ylabel "relative error ||u - u_FEM|| / ||u_FEM||" noenhanced
set yrange [5e-10:3]
$(panel cube "elastin cube, 1000 nodes, 10 N (labels: depth)")
$(panel organ "kidney-shaped organ, 10606 nodes, 1 N (labels: depth)")
unset multiplot
GP
echo "wrote $out.txt $out.json $out.dat docs/img/accuracy.png"
