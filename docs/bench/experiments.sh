#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/experiments.md and docs/stability.md: runs the paper's
# experiments and the stability sweep, keeps their tables and CSV under
# docs/bench/experiments/, and draws docs/img/{depth,tissue,anisotropy,stability}.png;
# docs/bench/volume.sh does the volume experiment (docs/img/volume-*.png).
#   docs/bench/experiments.sh [path/to/ftm] [--quick]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
shift || true
out=docs/bench/experiments
mkdir -p "$out" docs/img

"$ftm" experiment depth --csv-dir "$out" "$@" | tee "$out/depth.txt"
"$ftm" experiment tissue --csv-dir "$out" "$@" | tee "$out/tissue.txt"
"$ftm" experiment anisotropy --csv-dir "$out" "$@" | tee "$out/anisotropy.txt"

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# ---- depth: change(n) per k and mode; top-row profiles for k = 2 at t = 8 s
for k in 0.5 2 5; do
  for mode in 0 8; do
    awk -F, -v k=$k -v m=$mode 'NR > 1 && $1 == m && $2 == k { print $3, $4 }' \
      "$out/depth_change.csv" > "$tmp/change_${mode}_$k.dat"
  done
done
for n in 1 2 4 8 20; do
  awk -F, -v n=$n 'NR > 1 && $1 == 8 && $2 == 2 && $3 == n { print $4, $5 }' \
    "$out/depth_profiles.csv" > "$tmp/profile_$n.dat"
done
gnuplot <<GP
set terminal pngcairo size 1200,480 font "sans,10"
set output "docs/img/depth.png"
set multiplot layout 1,2 title "Optimum penetration depth (paper Figs. 9-10): 41x21 lattice, same force, mass, damping, time step"
set title "shape change from one more layer"
set xlabel "penetration depth n"
set ylabel "max |x(n+1) - x(n)| / max displacement"
set logscale y
set yrange [1e-4:1]
set grid
set key top right
plot "$tmp/change_8_0.5.dat" w lp lw 2 lc 1 pt 7 t "k = 0.5, t = 8 s", \
     "$tmp/change_8_2.dat" w lp lw 2 lc 2 pt 7 t "k = 2, t = 8 s", \
     "$tmp/change_8_5.dat" w lp lw 2 lc 3 pt 7 t "k = 5, t = 8 s", \
     "$tmp/change_0_0.5.dat" w l dt 2 lw 2 lc 1 t "k = 0.5, equilibrium", \
     "$tmp/change_0_2.dat" w l dt 2 lw 2 lc 2 t "k = 2, equilibrium", \
     "$tmp/change_0_5.dat" w l dt 2 lw 2 lc 3 t "k = 5, equilibrium", \
     0.05 w l lc rgb "black" dt 3 t "threshold 0.05"
unset logscale y
set yrange [*:*]
set title "top-row profile, k = 2, t = 8 s (cf. paper Fig. 9)"
set xlabel "x from the loaded node [spacings]"
set ylabel "vertical displacement / loaded node's at full depth"
set xrange [-10:10]
set key bottom right
plot for [n in "1 2 4 8 20"] "$tmp/profile_".n.".dat" w lp lw 2 t n." layers"
unset multiplot
GP

# ---- tissue: creep, hysteresis, load-deformation
for f in creep hysteresis rate; do
  for d in 1 2 4; do
    awk -F, -v d=$d 'NR > 1 && $1 == d { print $2, $3 }' "$out/tissue_$f.csv" > "$tmp/${f}_$d.dat"
  done
done
gnuplot <<GP
set terminal pngcairo size 1400,440 font "sans,10"
set output "docs/img/tissue.png"
set multiplot layout 1,3 title "Tissue responses (paper Fig. 11): 11x11 lattice pulled at the top, three nodal dampings d [N s/m]"
set grid
set key bottom right
set title "(a) creep under a constant force"
set xlabel "time [s]"
set ylabel "strain"
plot for [d in "1 2 4"] "$tmp/creep_".d.".dat" w l lw 2 t "d = ".d
set title "(b) hysteresis: force ramped up, then down"
set xlabel "force [N]"
plot for [d in "1 2 4"] "$tmp/hysteresis_".d.".dat" w l lw 2 t "d = ".d
set title "(c) force increased at a constant rate"
set key top left
plot for [d in "1 2 4"] "$tmp/rate_".d.".dat" w l lw 2 t "d = ".d
unset multiplot
GP

# ---- anisotropy: profiles across the loaded face
for m in 0 1 2; do
  for l in vertical horizontal; do
    awk -F, -v m=$m -v l=$l 'NR > 1 && $1 == m && $2 == l && $3 == "across" { print $4, $5 }' \
      "$out/anisotropy_profiles.csv" > "$tmp/an_${m}_$l.dat"
  done
done
gnuplot <<GP
set terminal pngcairo size 1200,480 font "sans,10"
set output "docs/img/anisotropy.png"
set multiplot layout 1,2 title "Anisotropy (paper Fig. 12): 11^3 lattice; A: horizontal springs k/10, B: 10k"
set grid
set xlabel "position across the loaded face, from the loaded node [spacings]"
set ylabel "displacement along the load [m]"
set title "displacement along the load, across the loaded face"
plot "$tmp/an_0_vertical.dat" w lp lw 2 lc 1 pt 7 t "isotropic, vertical load", \
     "$tmp/an_0_horizontal.dat" w lp lw 2 lc 1 pt 4 dt 2 t "isotropic, horizontal load", \
     "$tmp/an_1_vertical.dat" w lp lw 2 lc 2 pt 7 t "A, vertical", \
     "$tmp/an_1_horizontal.dat" w lp lw 2 lc 2 pt 4 dt 2 t "A, horizontal", \
     "$tmp/an_2_vertical.dat" w lp lw 2 lc 3 pt 7 t "B, vertical", \
     "$tmp/an_2_horizontal.dat" w lp lw 2 lc 3 pt 4 dt 2 t "B, horizontal"
set logscale y
set title "the same, log scale"
replot
unset multiplot
GP

# the stability sweep and its plot
docs/bench/stability.sh "$ftm" "$@"
# the volume in its control lattice (paper 4.2): the phantom, and the MRI if at hand
docs/bench/volume.sh "$ftm"
echo "wrote $out/* docs/img/depth.png docs/img/tissue.png docs/img/anisotropy.png docs/img/stability.png docs/img/volume-*.png"
