#!/usr/bin/env bash
# Reproduces docs/benchmarks.md's Table 3 section: runs `ftm bench table3`,
# keeps its table and JSON under docs/bench/, and draws docs/img/table3.png.
#   docs/bench/table3.sh [path/to/ftm] [--steps N]
set -euo pipefail
cd "$(dirname "$0")/../.."
ftm=${1:-build/release/tools/ftm}
shift || true
out=docs/bench
"$ftm" bench table3 "$@" | tee "$out/table3.txt"
"$ftm" bench table3 --json "$@" > "$out/table3.json"

# rows of the JSON -> whitespace table: depth nodes search step cached paper_search paper_step
tr '{' '\n' < "$out/table3.json" | grep '"depth"' | grep '"paper_step_ms"' |
  sed -E 's/.*"depth":([0-9.]+).*"nodes":([0-9.]+).*"search_us":([0-9.e+-]+).*"step_us":([0-9.e+-]+).*"step_cached_us":([0-9.e+-]+).*"paper_search_ms":([0-9.e+-]+).*"paper_step_ms":([0-9.e+-]+).*/\1 \2 \3 \4 \5 \6 \7/' \
  > "$out/table3.dat"

gnuplot <<GP
set terminal pngcairo size 900,560 font "sans,11"
set output "docs/img/table3.png"
set title "Paper Table 3: one step on a 50x50 lattice, force on the centre node"
set xlabel "nodes in the region (penetration depth 1..20)"
set ylabel "time per step [µs]"
set logscale xy
set grid
set key top left
plot "$out/table3.dat" using 2:(\$7*1000) with linespoints lw 2 title "paper: step (PIII 800 MHz)", \
     "$out/table3.dat" using 2:(\$6*1000) with linespoints lw 2 title "paper: neighbour search", \
     "$out/table3.dat" using 2:4 with linespoints lw 2 title "FTM: step with a fresh search", \
     "$out/table3.dat" using 2:5 with linespoints lw 2 title "FTM: step, layers cached", \
     "$out/table3.dat" using 2:3 with linespoints lw 2 title "FTM: neighbour search", \
     15 with lines dt 2 lc rgb "black" title "target 15 µs"
GP
echo "wrote $out/table3.txt $out/table3.json $out/table3.dat docs/img/table3.png"
