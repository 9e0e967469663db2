#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# What a trainee feels: `ftm bench feel` (docs/feel.md), the table, its JSON
# and the plot of force error against step time.
#   docs/bench/feel.sh [FTM]     (FTM: build/release/tools/ftm by default)
set -eu
ftm=${1:-build/release/tools/ftm}
here=$(cd "$(dirname "$0")" && pwd)
"$ftm" bench feel --plot "$here/../img/feel.png" | tee "$here/feel.txt"
"$ftm" bench feel --json >"$here/feel.json"
rm -f "$here/../img/feel.png.gp" "$here/../img/feel.png.dat"
