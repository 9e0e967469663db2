#!/usr/bin/env bash
# The main job, from a fresh clone: installs dependencies, builds, and runs a
# headless simulation of the default scene, printing its summary.
# Extra arguments go to `ftm sim` (e.g. a scene name or file, --steps N).
set -euo pipefail
cd "$(dirname "$0")/.."

deploy/install-deps.sh >&2
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release >&2
cmake --build build/release -j "$(nproc 2>/dev/null || echo 2)" >&2
exec build/release/tools/ftm sim "$@"
