#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server's recording on a disk that fills (loopback, a DDS domain and
# session of its own, `timeout` around every process): a session with two
# trainees records to a 256 KiB tmpfs made here. The disk fills within
# seconds; the recording stops for good with a logged error, the session
# goes on to its end (status 3), and the file keeps at least 90 % of the
# space that was free at the start as a recording that replays to where it
# stopped (whole chunks, and what fitted of the last one). Needs root to
# mount the tmpfs: skipped (77) otherwise; server_recfail.sh checks the
# same behaviour under a file size limit, without root.
set -u
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}"
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
skip() { echo "SKIP: $*"; exit 77; }
[ "$(id -u)" = 0 ] || skip "not root: mounting a tmpfs needs root (CAP_SYS_ADMIN)"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-fulldisk.XXXXXX")
disk="$dir/disk"
mkdir "$disk"
mount -t tmpfs -o size=256k,mode=0755 ftm-fulldisk "$disk" 2>"$dir/mount.err" || {
    e=$(cat "$dir/mount.err"); rm -rf "$dir"; skip "cannot mount a tmpfs: $e"; }
pids=
trap 'for p in $pids; do kill $p 2>/dev/null; done; umount "$disk" 2>/dev/null; rm -rf "$dir"' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.log "$dir"/*.out "$dir"/*.err; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done
    exit 1
}
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
common="--session srv-fulldisk-$$ --domain $domain --config $FTM_CONFIG"
rate=${FTM_TEST_RATE:-200}
cd "$dir" || fail "no $dir"
free=$(df -B1 --output=avail "$disk" | tail -n 1 | tr -d ' ')
[ "$free" -gt 200000 ] || fail "the tmpfs has only $free bytes free"

timeout 60 "$FTM_SERVER" --scene default $common --rate "$rate" --duration 7 \
    --record "$disk/s.rec" --report r.json --log s.log >s.out 2>s.err &
pids="$!"
server=$!
wait_for s.log "session 'srv-fulldisk" "server did not start"
timeout 60 "$FTM_BOT" --role trainee --script "$here/press-hold.bot" $common --id 11 \
    --duration 20 >bot11.out 2>bot11.err &
pids="$pids $!"
timeout 60 "$FTM_BOT" --role trainee --script "$here/press-still.bot" $common --id 12 \
    --duration 20 >bot12.out 2>bot12.err &
pids="$pids $!"
wait $server
rc=$?
[ "$rc" -eq 3 ] || fail "the disk filled: status $rc, not 3"
grep -q "error: recording $disk/s.rec: write failed: No space left on device; recording stopped for good at tick [0-9]*" s.log ||
    fail "no error for the full disk"
grep -q "shutting down (duration reached)" s.log || fail "the session did not run to its end"
grep -q "recording $disk/s.rec incomplete: stopped for good at tick [0-9]* ([0-9.]* s into the session) on a write error" s.log ||
    fail "the closing lines do not say the recording stopped"
grep -q '"recording":{"ok":false,"stopped_tick":' r.json || fail "the report does not say the recording stopped"
size=$(wc -c <"$disk/s.rec")
[ $(( size * 10 )) -ge $(( free * 9 )) ] ||
    fail "the recording kept $size bytes of the $free free at the start (< 90 %)"
timeout 60 "$FTM_SERVER" --replay "$disk/s.rec" >replay.out 2>replay.err ||
    fail "the recording of the full disk does not replay: $(grep -v info: replay.err | tail -1)"
grep -q "every hash equal" replay.out || fail "no replay summary"
grep -q "note: the recording ends at entry [0-9]* without the server's final status" replay.err ||
    fail "the replay did not say the recording was cut"
stopped=$(sed -n 's/.*recording stopped for good at tick \([0-9]*\) (\([0-9.]*\) s).*/tick \1, \2 s/p' s.log)
echo "fulldisk: $size of $free bytes free kept ($(( size * 1000 / free )) per mille), stopped at $stopped; $(sed -n 's/^ftm-server: //p' replay.out)"
echo "PASS fulldisk"
