#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The benchmark's offline ground truth (ftm-haptic-bench, the server's probe
# contact logic reproduced with libftm) against the server itself
# (ftm-server --offline): the same reaction force at every tick.
# Env: BENCH, SERVER (binaries), DATA (tests/client).
set -eu
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$BENCH" renderers --script "$DATA/press.bot" --delays 0 --trace "$tmp/bench.csv" > "$tmp/bench.txt"
ticks=$(sed -n 's/.* \([0-9][0-9]*\) ticks of .*/\1/p' "$tmp/bench.txt")
[ -n "$ticks" ] || { echo "no tick count in the benchmark's output"; cat "$tmp/bench.txt"; exit 1; }
"$SERVER" --offline "$ticks" --trainee 11:0:"$DATA/press.bot" --reactions "$tmp/server.csv" \
  > "$tmp/server.log" 2>&1 || { cat "$tmp/server.log"; exit 1; }
# bench: row k+1 (after the header) is tick k: t,hip_x,hip_z,fx,fz,...
# server: tick,participant,probe,fx,fy,fz for the ticks in contact only
awk -F, '
  FNR == 1 { next }
  FILENAME == ARGV[1] { sx[$1] = $4; sz[$1] = $6; n++; next }
  { k = FNR - 2; fx = (k in sx) ? sx[k] : 0; fz = (k in sz) ? sz[k] : 0
    d = fx - $4; if (d < 0) d = -d; e = fz - $5; if (e < 0) e = -e
    if (d > m) m = d; if (e > m) m = e
    if ($5 != 0) c++ }
  END {
    printf "server ticks in contact %d, bench %d, largest difference %.3g N\n", n, c, m
    if (n < 1000 || n != c || m > 1e-5) exit 1
  }' "$tmp/server.csv" "$tmp/bench.csv"
