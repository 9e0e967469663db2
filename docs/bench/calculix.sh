#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Reproduces the cube figures of docs/calculix.md: the paper's elastin cube
# at full depth pressed 10 mm (and 2 mm), each force model run to equilibrium
# against the stored CalculiX results (tests/calculix/ref), with steps and
# the median step time. Writes docs/bench/calculix.txt (the tables) and
# docs/bench/calculix.json (one JSON object per run, one per line).
#   docs/bench/calculix.sh [BUILD_DIR]     (default build/release)
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
cmp=$(cd "$build" && pwd)/tests/calculix/ccx_compare
out=$(pwd)/docs/bench/calculix
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cd tests/calculix
# springs need their own scene: the fitted stiffness (docs/fit.md, 2615.8 N/m
# at this spacing) and the interior nodes' lumped mass rho h^3
sed -e 's/^stiffness = 50 .*/stiffness = 2615.8/' -e 's/^mass = 0.001 .*/mass = 0.0014266117969821673/' \
  elastin-cube-10mm.scene >"$tmp/springs-10mm.scene"
: >"$out.json"
{
  echo "# docs/bench/calculix.sh, $(date -u +%Y-%m-%d), $(git rev-parse --short HEAD 2>/dev/null || echo '?')"
  echo "# elastin cube, 10 x 10 x 10 nodes, full depth 9, h = 2e-5 s; reference: CalculiX 2.20"
  for run in "elastin-cube-10mm.scene ref/elastin-cube-10mm.neo.dat neo-hookean" \
             "elastin-cube-10mm.scene ref/elastin-cube-10mm.neo.dat corot-fem" \
             "elastin-cube-10mm.scene ref/elastin-cube-10mm.neo.dat linear-fem" \
             "$tmp/springs-10mm.scene ref/elastin-cube-10mm.neo.dat springs" \
             "elastin-cube-2mm.scene ref/elastin-cube-2mm.linear.dat linear-fem"; do
    set -- $run
    echo
    echo "## $(basename "$1" .scene) against $(basename "$2" .dat), forces $3"
    "$cmp" sim "$1" "$2" --forces "$3" 2>&1
    "$cmp" sim "$1" "$2" --forces "$3" --json >>"$out.json" 2>/dev/null
  done
  # neo-Hookean at shallow depths: the paper's fixed far field and the elastic one
  for ff in elastic fixed; do
    for depth in 2 4 6; do
      echo
      echo "## elastin-cube-10mm against elastin-cube-10mm.neo, neo-hookean, depth $depth, far field $ff"
      "$cmp" sim elastin-cube-10mm.scene ref/elastin-cube-10mm.neo.dat --depth "$depth" --far-field "$ff" 2>&1
      "$cmp" sim elastin-cube-10mm.scene ref/elastin-cube-10mm.neo.dat --depth "$depth" --far-field "$ff" \
        --json >>"$out.json" 2>/dev/null
    done
  done
} | tee "$out.txt"
