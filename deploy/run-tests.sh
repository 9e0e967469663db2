#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# All tests, from a fresh clone: installs dependencies, then builds and runs
# the test suite twice, as a release build with warnings as errors and as an
# AddressSanitizer + UndefinedBehaviorSanitizer build; then every program is
# built with clang (warnings as errors) and the determinism tests run, the
# client's threaded tests run under ThreadSanitizer, and the fuzz targets run
# a short fixed-seed libFuzzer session each (docs/fuzzing.md).
set -euo pipefail
cd "$(dirname "$0")/.."

start=$(date +%s)
# a stage's heading, with the time since the start (CI's budget is 30 min)
stage() { echo "== $* [$(($(date +%s) - start)) s] =="; }

deploy/install-deps.sh

jobs=$(nproc 2>/dev/null || echo 2)
status=0
# The elastic far field's precomputation (docs/core.md, "Far field") is the
# same bits in every build: computed once by the release build below, then
# read by every test process of every build from this directory.
export FTM_CACHE_DIR="$PWD/build/ftm-cache"

stage "release build (-Werror)"
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DFTM_WERROR=ON
cmake --build build/release -j "$jobs"
build/release/tools/ftm sim default --steps 1 --quiet >/dev/null   # the default scene's far field
build/release/tools/ftm sim palpation --steps 1 --quiet >/dev/null # the main job's scene's
ctest --test-dir build/release --output-on-failure -j "$jobs" || status=1

# (the ASan build leaves out a few tests that check behaviour the same in
# every build, within CI's 30 minutes: the network-namespace tests, the
# window's frame-rate cap and reset, the session benchmarks' JSON)
# ftm-mesh (tools/mesher, C++ and CGAL: minutes to compile) is built and
# tested in the release build only
stage "ASan + UBSan build"
cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DFTM_WERROR=ON \
      -DFTM_SANITIZE=address,undefined -DFTM_BUILD_MESHER=OFF
cmake --build build/asan -j "$jobs"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build/asan --output-on-failure -j "$jobs" || status=1

# clang builds every program FTM ships (libraries, server, client, bot, the
# ftm tool) with warnings as errors, and the two golden-hash tests; the other
# tests' sources are GCC's alone here, within CI's 30 minutes (the fuzz stage
# below builds the core, wire and session code with clang -Werror again)
stage "clang build (-Werror, every program): the golden hashes must match GCC's bit for bit"
CC=clang cmake -S . -B build/clang -G Ninja -DCMAKE_BUILD_TYPE=Release -DFTM_WERROR=ON \
      -DFTM_BUILD_MESHER=OFF
cmake --build build/clang -j "$jobs" --target ftm_server ftm_client ftm_haptic_bench ftm_bot \
      ftm_cli test_determinism test_sim_kernel
ctest --test-dir build/clang --output-on-failure -R 'test_determinism|test_sim_kernel' || status=1

stage "ThreadSanitizer build: the client's threads (haptic loop and its exchanges)"
cmake -S . -B build/tsan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DFTM_WERROR=ON -DFTM_SANITIZE=thread \
      -DFTM_BUILD_MESHER=OFF
cmake --build build/tsan -j "$jobs" --target test_haptic test_haptic_loop
TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 \
  ctest --test-dir build/tsan --output-on-failure -R '^test_haptic(_loop)?$' || status=1

stage "fuzz targets (clang, libFuzzer, ASan+UBSan): a fixed number of inputs from seed 1"
# campaigns proper are run by hand (docs/fuzzing.md); the corpus itself is
# replayed by CTest in every build above
tests/fuzz/run.sh --build build/fuzz --build-only fuzz_scene fuzz_mesh fuzz_nifti fuzz_labels \
    fuzz_wire fuzz_record fuzz_script fuzz_stl fuzz_replica fuzz_session || status=1
# fuzz_replica and fuzz_session run a whole replica or session core per
# input (3-7 inputs/s): 60 each beyond the corpus, which is replayed first;
# they take as long as all the others, so they run on the other core
tests/fuzz/run.sh --build build/fuzz --no-build --runs 60 fuzz_replica fuzz_session \
    >build/fuzz/slow.log 2>&1 &
slow=$!
tests/fuzz/run.sh --build build/fuzz --no-build --runs 3000 fuzz_scene fuzz_mesh fuzz_nifti \
    fuzz_labels fuzz_wire fuzz_record fuzz_script || status=1
# fuzz_stl: Assimp leaks on most malformed files, and each leak makes
# libFuzzer run a whole leak check (10 ms): 1000 inputs take 10 s
tests/fuzz/run.sh --build build/fuzz --no-build --runs 1000 fuzz_stl || status=1
wait $slow || status=1
cat build/fuzz/slow.log

stage "done: status $status"
exit $status
