#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Fuzz campaigns (docs/fuzzing.md). Builds the libFuzzer targets with clang,
# ASan and UBSan in BUILD (default build/fuzz), then runs each TARGET (default:
# all) for SECONDS (default 300) on a scratch copy of its committed corpus.
# A finding is saved as BUILD/findings/TARGET/crash-* (or timeout-*, oom-*)
# and the script exits 1. With --merge, the inputs that reached new
# coverage are merged back into tests/fuzz/corpus/TARGET (minimised).
# With --runs N each target instead runs N inputs from a fixed seed: the same
# inputs on every run of the same build (CI's smoke run). --build-only builds
# the targets and stops; --no-build runs them as last built (so that CI can
# run two sets at once on one build).
#   tests/fuzz/run.sh [--merge] [--build DIR] [--runs N] [--build-only|--no-build]
#                     [SECONDS] [TARGET...]
# (SECONDS is ignored with --runs)
set -euo pipefail
cd "$(dirname "$0")/../.."
merge=0
runs=0
build=build/fuzz
make=1
while [ $# -gt 0 ]; do
    case $1 in
    --merge) merge=1; shift ;;
    --build) build=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --build-only) make=2; shift ;;
    --no-build) make=0; shift ;;
    *) break ;;
    esac
done
seconds=300
case ${1:-} in [0-9]*) seconds=$1; shift ;; esac
case $build in /*) ;; *) build="$PWD/$build" ;; esac
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_scene fuzz_mesh fuzz_nifti fuzz_labels fuzz_stl fuzz_wire fuzz_record fuzz_script fuzz_replica fuzz_session)
case $seconds in *[!0-9]* | '') echo "run.sh: SECONDS must be a whole number, got '$seconds'" >&2; exit 2 ;; esac
case $runs in *[!0-9]* | '') echo "run.sh: --runs needs a whole number, got '$runs'" >&2; exit 2 ;; esac
if [ "$runs" -gt 0 ]; then
    budget=(-runs="$runs" -seed=1)
    what="$runs inputs, seed 1"
else
    budget=(-max_total_time="$seconds")
    what="$seconds s"
fi

# (client/ configured too: fuzz_script reads scripts through its haptic
# device; only the targets named are built)
if [ $make -gt 0 ]; then
    CC=clang cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFTM_FUZZ=ON \
        -DFTM_WERROR=ON -DFTM_SANITIZE=address,undefined -DFTM_BUILD_MESHER=OFF >/dev/null
    cmake --build "$build" --target "${targets[@]}"
    [ $make = 1 ] || exit 0
fi

# Assimp's leak on malformed STL files is suppressed (lsan.supp says why)
export LSAN_OPTIONS="suppressions=$PWD/tests/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
status=0
for t in "${targets[@]}"; do
    [ -d "tests/fuzz/corpus/$t" ] || { echo "run.sh: unknown target '$t'" >&2; exit 2; }
    work="$build/campaign/$t"
    found="$build/findings/$t"
    rm -rf "$work"
    mkdir -p "$work" "$found"
    cp "tests/fuzz/corpus/$t"/* "$work/"
    echo "== $t: $what"
    # -close_fd_mask=3: the parsers' own messages would drown the log; ASan's
    # reports and fuzz_check's (fuzz_util.c) still get through
    if ! (cd "$found" && "$build/tests/fuzz/$t" "${budget[@]}" -timeout=10 \
            -rss_limit_mb=3000 -close_fd_mask=3 -print_final_stats=1 \
            "$work") >"$build/findings/$t.log" 2>&1; then
        echo "FINDING in $t: $(ls "$found")"
        grep -m 3 -E "ERROR|property failed|runtime error" "$build/findings/$t.log" || true
        status=1
    fi
    grep -E "stat::number_of_executed_units|cov:" "$build/findings/$t.log" | tail -n 2
    if [ $merge = 1 ] && [ $status = 0 ]; then
        "$build/tests/fuzz/$t" -merge=1 -close_fd_mask=3 "tests/fuzz/corpus/$t" "$work" \
            >"$build/findings/$t.merge.log" 2>&1
        echo "   corpus: $(ls "tests/fuzz/corpus/$t" | wc -l) files"
    fi
done
exit $status
