#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/fit.md's table and plot: runs `ftm fit elastin-cube --json
# --trace` (seed 1, settle mode, both models), keeps the JSON and the
# optimiser trace under docs/bench/fit/, and draws docs/img/fit_elastin_cube.png.
#   docs/bench/fit.sh [path/to/ftm] [fit options]
#   docs/bench/fit.sh --plot-only    (redraw from docs/bench/fit/)
set -euo pipefail
cd "$(dirname "$0")/../.."
out=docs/bench/fit
mkdir -p "$out" docs/img
if [ "${1:-}" != --plot-only ]; then
  ftm=${1:-build/release/tools/ftm}
  shift || true
  "$ftm" fit elastin-cube --json --quiet --trace "$out/elastin_cube_trace.csv" "$@" \
    > "$out/elastin_cube.json"
fi

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# trace: run,iteration,evaluations,temperature,current,best -> one file per run
awk -F, -v dir="$tmp" 'NR > 1 { f = $1; gsub(/\//, "_", f); print $3, $5, $6 > (dir "/" f ".dat") }' \
  "$out/elastin_cube_trace.csv"
# errors per load case: force avg max, for the paper and each fit
python3 - "$out/elastin_cube.json" "$tmp" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
with open(sys.argv[2] + "/paper.dat", "w") as f:
    for c in d["paper"]:
        f.write(f'{c["force"]} {c["avg_err_pct"]} {c["max_err_pct"]}\n')
for fit in d["fits"]:
    with open(f'{sys.argv[2]}/err_{fit["model"]}_{fit["method"]}.dat', "w") as f:
        for c in fit["cases"]:
            f.write(f'{c["force"]} {c["avg_err_pct"]} {c["max_err_pct"]}\n')
PY
gnuplot <<GP
set terminal pngcairo size 1200,480 font "sans,10"
set termoption noenhanced
set output "docs/img/fit_elastin_cube.png"
set multiplot layout 1,2 title "ftm fit elastin-cube (seed 1, settle mode, 18-neighbour stencil, total force over the four top nodes)"
set title "cost of Eq. 17 / cost at the start, per evaluation"
set xlabel "cost evaluations"
set ylabel "normalised cost"
set logscale y
set yrange [0.1:10]
set grid
set key top right
plot "$tmp/uniform_anneal.dat" using 1:2 w l lc rgb "#8080c0" t "uniform k, annealing: current", \
     "" using 1:3 w l lw 2 lc rgb "#2030a0" t "uniform k, annealing: best", \
     "$tmp/uniform_nelder-mead.dat" using 1:3 w lp pt 7 ps 0.5 lc rgb "#20a0a0" t "uniform k, Nelder-Mead: best", \
     "$tmp/classes_anneal.dat" using 1:2 w l lc rgb "#d09090" t "per class, annealing: current", \
     "" using 1:3 w l lw 2 lc rgb "#a02020" t "per class, annealing: best", \
     "$tmp/classes_nelder-mead.dat" using 1:3 w lp pt 7 ps 0.5 lc rgb "#20a020" t "per class, Nelder-Mead: best"
set title "nodal error, % of the spring length (paper Tables 1-2 against these fits)"
set xlabel "total force [N]"
set ylabel "error [% of spring length]"
set yrange [0.1:1000]
set xrange [5:45]
set key top left maxrows 4 font ",9"
plot "$tmp/paper.dat" using 1:3 w lp pt 5 dt 2 lc rgb "black" t "paper max", \
     "" using 1:2 w lp pt 4 lc rgb "black" t "paper avg", \
     "$tmp/err_uniform_anneal.dat" using 1:3 w lp pt 7 dt 2 lc rgb "#2030a0" t "uniform, annealing max", \
     "" using 1:2 w lp pt 6 lc rgb "#2030a0" t "uniform, annealing avg", \
     "$tmp/err_classes_anneal.dat" using 1:3 w lp pt 7 dt 2 lc rgb "#a02020" t "per class, annealing max", \
     "" using 1:2 w lp pt 6 lc rgb "#a02020" t "per class, annealing avg", \
     "$tmp/err_classes_nelder-mead.dat" using 1:3 w lp pt 9 dt 2 lc rgb "#20a020" t "per class, Nelder-Mead max", \
     "" using 1:2 w lp pt 8 lc rgb "#20a020" t "per class, Nelder-Mead avg"
unset multiplot
GP
echo "wrote $out/elastin_cube.json $out/elastin_cube_trace.csv docs/img/fit_elastin_cube.png"
