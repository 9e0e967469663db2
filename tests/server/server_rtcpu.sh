#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server --rt-cpu: where the real-time tick and publishing threads run.
#   - --check says whether the CPU can be used (a CPU that is not there
#     cannot), and a session started with it says so in its log (warn);
#   - --rt-cpu N pins both threads on N, --rt-cpu any pins neither, as the
#     log line and the threads' affinity (/proc) say.
# Where the host permits no real-time scheduling, the threads are never
# pinned: that is checked instead.
set -u
fail() { echo "FAIL: $*"; for f in "$dir"/*.out; do echo "== $f"; cat "$f"; done; exit 1; }
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-rtcpu.XXXXXX")
trap 'rm -rf "$dir"' EXIT
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
common="--session srv-rtcpu-$$ --domain $domain --config $FTM_CONFIG --rate ${FTM_TEST_RATE:-200}"
last=$(( $(nproc) - 1 ))

cd "$dir" || fail "no $dir"
# shellcheck disable=SC2086
timeout 30 "$FTM_SERVER" $common --check --rt-cpu 1000 >check.out 2>&1 || fail "--check failed"
if grep -q "real-time   not permitted" check.out; then
    # shellcheck disable=SC2086
    timeout 30 "$FTM_SERVER" $common --duration 1 --rt-cpu "$last" >run.out 2>&1 ||
        fail "a session with --rt-cpu $last failed"
    grep -q "real-time scheduling not permitted" run.out || fail "not permitted, but not said"
    echo "PASS rt-cpu: real-time scheduling not permitted here, and said so"
    exit 0
fi
grep -q "real-time   cpu 1000 not permitted (Invalid argument)" check.out ||
    fail "--check --rt-cpu 1000: not refused"
# shellcheck disable=SC2086
timeout 30 "$FTM_SERVER" $common --check --rt-cpu "$last" >check2.out 2>&1 || fail "--check failed"
grep -q "real-time   cpu $last permitted" check2.out || fail "--check --rt-cpu $last: not permitted"

# a running server: the log says where the threads are, and /proc agrees
run() { # name options...
    n=$1
    shift
    # shellcheck disable=SC2086
    timeout 30 "$FTM_SERVER" $common --duration 3 "$@" >"$n.out" 2>&1 &
    tpid=$!
    i=0
    until grep -q "tick thread SCHED_FIFO" "$n.out" 2>/dev/null; do
        i=$((i + 1))
        [ $i -lt 100 ] || fail "$n: no scheduling line"
        sleep 0.05
    done
    pid=$(pgrep -P $tpid) || fail "$n: no server process under timeout"
    # the threads running SCHED_FIFO (policy 1, field 41 of stat) and their CPUs
    fifo=
    for t in "/proc/$pid/task/"*; do
        pol=$(sed 's/.*) //' "$t/stat" | cut -d' ' -f39)
        [ "$pol" = 1 ] && fifo="$fifo $(sed -n 's/^Cpus_allowed_list:[[:space:]]*//p' "$t/status")"
    done
    wait $tpid || fail "$n: the session failed"
}
run pinned --rt-cpu "$last"
grep -q "publishing thread 11, both on cpu $last\$" pinned.out || fail "--rt-cpu $last: not pinned"
[ "$fifo" = " $last $last" ] || fail "--rt-cpu $last: real-time threads on CPUs '$fifo'"
run any --rt-cpu any
grep -q "on no CPU in particular (--rt-cpu any)" any.out || fail "--rt-cpu any: pinned"
all=$(sed -n 's/^Cpus_allowed_list:[[:space:]]*//p' /proc/self/status)
[ "$fifo" = " $all $all" ] || fail "--rt-cpu any: real-time threads on CPUs '$fifo', not '$all'"
run absent --rt-cpu 1000
grep -q "warn: tick thread .* on no CPU in particular (cpu 1000 not permitted)" absent.out ||
    fail "--rt-cpu 1000: no warning"
echo "PASS rt-cpu: --check tells a usable CPU; N pins both threads on N, any pins neither"
