#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# docs/img/speed.png from docs/bench/speed-revisions.dat: each element model's
# step over the spring step, by arithmetic revision (the mean of the runs
# quoted in docs/speed.md), with issue 32's targets (4x and 6x).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
awk '!/^#/ && NF {
    n = 0
    for (r = 0; r < 4; r++) {
        s = 0; c = 0
        for (k = 0; k < 3; k++) { v = $(2 + 3 * r + k); if (v != "-") { s += v; c++ } }
        m[r] = s / c
    }
    match($0, /"[^"]*"/); name = substr($0, RSTART, RLENGTH)
    print name, m[0], m[1], m[2], m[3]
}' "$here/speed-revisions.dat" >"$here/speed-revisions.means"
gnuplot <<GP
set terminal pngcairo size 900,480 font ",11"
set output "$here/../img/speed.png"
set title "Element forces beside springs: the elastin cube, full depth (ftm bench accuracy --speed)"
set ylabel "step / spring step"
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.8 border -1
set boxwidth 0.9
set yrange [0:9]
set bmargin 4
set grid ytics
set key top right
set arrow from graph 0, first 4 to graph 1, first 4 nohead dt 2 lc rgb "#aa0000"
set label "co-rotational target 4x" at graph 0.01, first 4.25 tc rgb "#aa0000"
set arrow from graph 0, first 6 to graph 1, first 6 nohead dt 3 lc rgb "#555555"
set label "neo-Hookean target 6x" at graph 0.01, first 6.25 tc rgb "#555555"
plot "$here/speed-revisions.means" using 2:xtic(1) title "revision 3" lc rgb "#bbbbbb", \
     "" using 3 title "revision 4" lc rgb "#6699cc", \
     "" using 4 title "revision 5" lc rgb "#224488", \
     "" using 5 title "revision 6" lc rgb "#112244"
GP
rm -f "$here/speed-revisions.means"
