#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/stability.md: runs the stability sweep (`ftm stability`),
# keeps its table and CSV under docs/bench/experiments/, and draws
# docs/img/stability.png. Also called by docs/bench/experiments.sh.
#   docs/bench/stability.sh [path/to/ftm] [--quick]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
shift || true
out=docs/bench/experiments
mkdir -p "$out" docs/img
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# exit status 1 means a NaN or an unnoticed instability: keep the table anyway
"$ftm" stability --csv "$out/stability.csv" "$@" | tee "$out/stability.txt" || true

# ---- stability: measured boundary against the theoretical limits, and
# against damping. The damping ratio is d/2m / (0.025 w_max), the sweep's unit;
# the core warns when d/2m < 0.11 w_max h/h_crit, i.e. above h/h_crit = ratio / 4.4
# index, measured (<0: unstable at every step tried -> drawn at 0.05), spectral ratio, damping ratio, name
awk -F, 'NR > 1 { gsub(/"/, "", $2); m = $9 < 0 ? 0.05 : $9; print $1, m, $6, $7, "\"" $2 "\"" }' \
  "$out/stability.csv" > "$tmp/stab.dat"
# 2D damping series (base and "d = ..."): measured boundaries, and those unstable at every step
awk 'NR == 1 || /"d = / { if ($4 > 0 && $2 > 0.05) print $4, $2 }' "$tmp/stab.dat" | sort -g > "$tmp/stab_damping.dat"
awk '/"d = / { if ($4 > 0 && $2 == 0.05) print $4, $2 }' "$tmp/stab.dat" | sort -g > "$tmp/stab_damping_none.dat"
# guarded runs: index, largest displacement / spacing at the first unstable step and at 2x, name
awk -F, 'NR > 1 && $10 == 1 { gsub(/"/, "", $2); print $1, $19, $20, "\"" $2 "\"" }' \
  "$out/stability.csv" > "$tmp/stab_guard.dat"
gnuplot <<GP
set terminal pngcairo size 2000,600 font "sans,10"
set termoption noenhanced
set output "docs/img/stability.png"
set multiplot layout 1,3 title "Stability sweep: largest stable time step (guard off) in units of the core's h_crit (Gershgorin bound), and what the guard does beyond it"
set title "every configuration"
set ylabel "h / h_crit"
set logscale y
set yrange [0.04:6]
set grid ytics
set xtics rotate by -40 scale 0 font ",9"
set key top left font ",9"
set bmargin 10
plot "$tmp/stab.dat" using 1:2:xtic(5) w p pt 7 ps 1.5 t "measured boundary (0.05: unstable at every step tried)", \
     "" using 1:3 w p pt 6 ps 1.5 t "spectral limit 2/sqrt(lambda_max) of undamped central differences", \
     1 w l lc rgb "black" dt 2 t "h_crit"
set title "2D lattice: boundary against nodal damping"
set xlabel "damping ratio d/2m / (0.025 w_max)   (the core warns when h/h_crit > ratio / 4.4)"
set logscale x
set xrange [0.1:200]
set xtics norotate auto font ",10"
set bmargin 4
set key bottom right
plot "$tmp/stab_damping.dat" w lp pt 7 ps 1.5 lw 2 t "measured boundary", \
     "$tmp/stab_damping_none.dat" w p pt 6 ps 2 lw 2 t "unstable at every step tried (drawn at 0.05)", \
     0.225 * x w l dt 2 lw 2 t "fit: 0.225 x ratio", \
     x / 4.4 w l dt 4 lw 2 lc rgb "red" t "the core's warning: warns above ratio / 4.4", \
     1 w l lc rgb "black" dt 3 t "h_crit"
set title "guard on, beyond the boundary: largest displacement in the run"
set xlabel ""
unset logscale x
set xrange [*:*]
set autoscale x
set ylabel "largest displacement / mean spacing"
set logscale y
set yrange [1e-3:1e4]
set xtics rotate by -40 scale 0 font ",9"
set bmargin 10
set key top left
plot "$tmp/stab_guard.dat" using 1:2:xtic(4) w p pt 7 ps 1.5 t "at the first unstable step", \
     "" using 1:3 w p pt 6 ps 1.5 t "at twice that step", \
     1 w l lc rgb "black" dt 2 t "one spacing (the static load gives ~0.02)"
unset multiplot
GP
