#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces docs/benchmarks.md's Table 3 section: runs `ftm bench table3`,
# keeps its table and JSON under docs/bench/, and draws docs/img/table3.png.
#   docs/bench/table3.sh [path/to/ftm] [--steps N]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
shift || true
out=docs/bench
# one run: the table to the terminal and table3.txt, the same run's JSON to table3.json
"$ftm" bench table3 --json-file "$out/table3.json" "$@" | tee "$out/table3.txt"

# rows of the JSON -> whitespace table: depth nodes search step cached paper_search paper_step
# jacobi_search jacobi_step jacobi_cached
tr '{' '\n' < "$out/table3.json" | grep '"paper_step_ms"' |
  perl -ne 'my %v = /"(\w+)":([0-9.e+-]+)/g;
    print join(" ", @v{qw(depth nodes search_us step_us step_cached_us paper_search_ms
      paper_step_ms jacobi_search_us jacobi_step_us jacobi_step_cached_us)}), "\n"' \
  > "$out/table3.dat"

gnuplot <<GP
set terminal pngcairo size 900,560 font "sans,11"
set output "docs/img/table3.png"
set title "Paper Table 3: one step on a 50x50 lattice, force on the centre node"
set xlabel "nodes in the region (penetration depth 1..20)"
set ylabel "time per step [µs]"
set logscale xy
set grid
set key bottom right font ",9"
plot "$out/table3.dat" using 2:(\$7*1000) with linespoints lw 2 title "paper: step (PIII 800 MHz)", \
     "$out/table3.dat" using 2:(\$6*1000) with linespoints lw 2 title "paper: neighbour search", \
     "$out/table3.dat" using 2:4 with linespoints lw 2 title "FTM colored: step with a fresh search", \
     "$out/table3.dat" using 2:5 with linespoints lw 2 title "FTM colored: step, layers cached", \
     "$out/table3.dat" using 2:3 with linespoints lw 2 title "FTM colored: neighbour search", \
     "$out/table3.dat" using 2:9 with linespoints lw 2 dt 3 title "FTM jacobi: step with a fresh search", \
     "$out/table3.dat" using 2:10 with linespoints lw 2 dt 3 title "FTM jacobi: step, layers cached", \
     "$out/table3.dat" using 2:8 with linespoints lw 2 dt 3 title "FTM jacobi: neighbour search", \
     15 with lines dt 2 lc rgb "black" title "target 15 µs"
GP
echo "wrote $out/table3.txt $out/table3.json $out/table3.dat docs/img/table3.png"
