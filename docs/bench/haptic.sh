#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Haptic benchmarks (docs/haptics.md): the loop's timing and the two force
# renderers against a 1 kHz ground-truth force trace under injected delay.
# Usage: docs/bench/haptic.sh [path/to/ftm-haptic-bench]
# Writes docs/bench/haptic_{timing,press,circle}.{txt,json} and
# docs/img/haptic_renderers.png.
set -eu
cd "$(dirname "$0")/../.."
bench=${1:-build/release/client/ftm-haptic-bench}
out=docs/bench
img=docs/img
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$bench" timing --seconds 10 --repeat 3 | tee $out/haptic_timing.txt
"$bench" timing --seconds 10 --repeat 3 --json > $out/haptic_timing.json
for path in press circle; do
  "$bench" renderers --path $path --trace "$tmp/$path.csv" | tee $out/haptic_$path.txt
  "$bench" renderers --path $path --json > $out/haptic_$path.json
done

# RMS error and work against delay, one data block per renderer
python3 - "$out" "$tmp" <<'PY'
import json, sys
out, tmp = sys.argv[1], sys.argv[2]
for path in ("press", "circle"):
    d = json.load(open(f"{out}/haptic_{path}.json"))["renderers"]["rows"]
    with open(f"{tmp}/{path}_rms.dat", "w") as f:
        for r in ("hold", "extrapolate", "model", "model-held"):
            f.write(f"# {r}\n")
            for row in d:
                if row["renderer"] == r:
                    f.write(f"{row['delay_ms']} {row['rms_N']} {row['work_mJ']}\n")
            f.write("\n\n")
PY

# columns of the trace: 1 t, 3 hip_z, 5 truth_fz, then fx,fz per delay x renderer
# (delays 0,20,50,100; renderers hold, extrapolate, model, model-held):
# delay index d, renderer r -> fz column 5 + 2 * (4 * d + r) + 2
col() { echo $((5 + 2 * (4 * $1 + $2) + 2)); }
gnuplot <<GP
set terminal pngcairo size 1200,900 font "sans,10"
set output "$img/haptic_renderers.png"
set datafile separator ","
names = "hold extrapolate model model-held"
set multiplot layout 2,2 title "Haptic force renderers against the 1 kHz ground truth (default scene)"
set key top left
set xlabel "time [s]"; set ylabel "force z [N]"
set title "circle path, samples 50 ms late"
plot "$tmp/circle.csv" u 1:5 w l lw 2 lc rgb "black" t "ground truth", \
     "" u 1:$(col 2 0) w l lc rgb "#999999" t "hold", \
     "" u 1:$(col 2 1) w l lc rgb "#d62728" t "extrapolate", \
     "" u 1:$(col 2 2) w l lc rgb "#1f77b4" t "model", \
     "" u 1:$(col 2 3) w l dt 2 lc rgb "#1f77b4" t "model-held"
set title "press path, samples 100 ms late"
plot "$tmp/press.csv" u 1:5 w l lw 2 lc rgb "black" t "ground truth", \
     "" u 1:$(col 3 0) w l lc rgb "#999999" t "hold", \
     "" u 1:$(col 3 1) w l lc rgb "#d62728" t "extrapolate", \
     "" u 1:$(col 3 2) w l lc rgb "#1f77b4" t "model", \
     "" u 1:$(col 3 3) w l dt 2 lc rgb "#1f77b4" t "model-held"
set datafile separator whitespace
set xlabel "injected delay [ms]"; set ylabel "RMS force error [N]"
set title "RMS error (solid: circle path, dashed: press path)"
set key top left
plot for [i=0:3] "$tmp/circle_rms.dat" index i u 1:2 w lp pt 7 lc i+1 t word(names, i+1), \
     for [i=0:3] "$tmp/press_rms.dat" index i u 1:2 w lp pt 6 dt 2 lc i+1 notitle
set ylabel "work on the hand over the path [mJ]  (> 0: energy injected)"
set title "Passivity: closed-path work (truth: circle -9.8 mJ, press -4.3 mJ)"
plot for [i=0:3] "$tmp/circle_rms.dat" index i u 1:3 w lp pt 7 lc i+1 t word(names, i+1), \
     for [i=0:3] "$tmp/press_rms.dat" index i u 1:3 w lp pt 6 dt 2 lc i+1 notitle, \
     0 w l lc rgb "black" notitle
unset multiplot
GP
echo "wrote $img/haptic_renderers.png"
