#!/usr/bin/env bash
# Reproduces docs/accuracy.md: runs `ftm bench accuracy` once (both bodies),
# keeps its table, JSON and gnuplot data under docs/bench/, and draws
# docs/img/accuracy.png (error against time to equilibrium, Pareto fronts).
#   docs/bench/accuracy.sh [path/to/ftm] [bench options, e.g. --mesh cube]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
shift || true
out=docs/bench/accuracy
"$ftm" bench accuracy --save "$out" "$@"

dat="$out.dat"
# rows of one body and method: mesh method depth nodes h step_us steps time_s setup_s error
sel() { echo "< awk '\$1==\"$1\" && \$2==\"$2\"' $dat"; }
panel() { # $1 = body, $2 = title
  cat <<GP
set title "$2"
plot $(sel "$1" ft-springs)      using 8:(\$10<1e-9?1e-9:\$10) with linespoints lw 2 pt 7 lc rgb "#1f77b4" title "transmittal, springs (depth 1..full)", \
     $(sel "$1" ft-springs)      using 8:(\$10<1e-9?1e-9:\$10):3 with labels offset 0,0.8 tc rgb "#1f77b4" notitle, \
     $(sel "$1" ft-fem)          using 8:(\$10<1e-9?1e-9:\$10) with linespoints lw 2 pt 5 lc rgb "#d62728" title "transmittal, linear FEM forces (depth 1..full)", \
     $(sel "$1" ft-fem)          using 8:(\$10<1e-9?1e-9:\$10):3 with labels offset 0,-0.9 tc rgb "#d62728" notitle, \
     $(sel "$1" ft-corot)        using 8:(\$10<1e-9?1e-9:\$10) with points ps 1.6 pt 9 lc rgb "#9467bd" title "transmittal, co-rotational FEM forces (full)", \
     $(sel "$1" explicit-springs) using 8:(\$10<1e-9?1e-9:\$10) with points ps 1.6 pt 11 lc rgb "#2ca02c" title "explicit mass-spring, all nodes", \
     $(sel "$1" implicit-springs) using 8:(\$10<1e-9?1e-9:\$10) with points ps 1.6 pt 13 lc rgb "#ff7f0e" title "backward Euler mass-spring (constant tangent)", \
     $(sel "$1" implicit-newton) using 8:(\$10<1e-9?1e-9:\$10) with points ps 1.6 pt 12 lc rgb "#8c564b" title "backward Euler mass-spring (Newton)", \
     $(sel "$1" fem-cholmod)     using 8:(1e-9) with points ps 2 pt 3 lc rgb "black" title "linear FEM, prefactored CHOLMOD (error 0: drawn at 1e-9)", \
     $(sel "pareto-$1" ft-springs) using 8:(\$10<1e-9?1e-9:\$10) with lines lw 6 lc rgb "#40808080" notitle, \
     "< awk '\$1==\"pareto-$1\"' $dat" using 8:(\$10<1e-9?1e-9:\$10) with steps lw 8 lc rgb "#b0808080" title "Pareto front"
GP
}
gnuplot <<GP
set terminal pngcairo size 1500,620 font "sans,10"
set output "docs/img/accuracy.png"
set multiplot layout 1,2
set logscale xy
set grid
set key bottom left font "sans,8"
set xlabel "time to equilibrium per load [s]  (steps x median step; set-up not included)"
set ylabel "relative error ||u - u_FEM|| / ||u_FEM||"
set yrange [5e-10:3]
$(panel cube "elastin cube, 1000 nodes, 10 N (labels: depth)")
$(panel organ "kidney-shaped organ, 10606 nodes, 1 N (labels: depth)")
unset multiplot
GP
echo "wrote $out.txt $out.json $out.dat docs/img/accuracy.png"
