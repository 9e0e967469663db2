#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server's recording and report when things go wrong (loopback, a DDS
# domain and session of its own, `timeout` around every process):
#   killed:  a session with a pressing trainee, the server SIGKILLed after
#            about 2.5 s: the recording has reached the file (chunks of
#            100 ms, written as they fill), replays with every hash equal and a
#            note that it was cut, and its report has the trainee's touch;
#   fsize:   a session under a file size limit (ulimit -f) smaller than its
#            recording: the write fails (EFBIG), the recording stops for
#            good with a logged error, the session goes on to its end and
#            the server exits 3 — not killed by SIGXFSZ; the file keeps its
#            whole chunks and what fitted of the failed one, >= 90 % of the
#            limit, and replays to there; the metrics (ftm_record_ok 0,
#            ftm_record_errors_total 1, ftm_record_bytes the file's size),
#            the closing lines and the report say when and why it stopped
#            (a full disk itself: server_fulldisk.sh, as root);
#   report:  a report that cannot be written (ulimit -f 0) leaves the
#            previous file as it was and no temporary file; status 3;
#   nostart: a server that cannot start (its metrics port taken) leaves
#            no recording in its --record-dir.
set -u
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}"
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-recfail.XXXXXX")
server=
trap '[ -n "$server" ] && kill $server 2>/dev/null; rm -rf "$dir"' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.log "$dir"/*.out "$dir"/*.err; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done
    exit 1
}
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
common="--session srv-recfail-$$ --domain $domain --config $FTM_CONFIG"
rate=${FTM_TEST_RATE:-200}
cd "$dir" || fail "no $dir"

# killed: SIGKILL mid-session (no `timeout` around the server: $! must be it)
"$FTM_SERVER" --scene default $common --rate "$rate" --record k.rec --log k.log \
    >k.out 2>k.err &
server=$!
wait_for k.log "session 'srv-recfail" "server did not start"
timeout 60 "$FTM_BOT" --role trainee --script "$here/press-hold.bot" $common --id 11 \
    --duration 20 >bot.out 2>bot.err &
bot=$!
wait_for k.log "participant 11 probe 0: contact" "the trainee did not touch" 300
sleep 1.2 # past a flush of the contact
kill -KILL $server
wait $server
server=
kill $bot 2>/dev/null
wait $bot
[ -s k.rec ] || fail "the killed server's recording is empty"
timeout 60 "$FTM_SERVER" --replay k.rec --report k.json >replay.out 2>replay.err ||
    fail "the killed server's recording does not replay: $(grep -v info: replay.err | tail -1)"
grep -q "note: the recording ends at entry [0-9]* without the server's final status" replay.err ||
    fail "the replay did not say the recording was cut"
grep -q "every hash equal" replay.out || fail "no replay summary"
grep -q '"touches":1,' k.json || fail "the replay's report has no touch"
timeout 60 "$FTM_SERVER" --inputs k.rec >inputs.out 2>inputs.err || fail "--inputs of it failed"
grep -q "note: the recording ends at entry" inputs.err || fail "--inputs did not say it was cut"
echo "killed: $(wc -c <k.rec) bytes; $(sed -n 's/^ftm-server: //p' replay.out)"

# fsize: 120 blocks allowed (60 KiB: sh counts 512-byte blocks), which the
# trainee's joining and press pass within a few seconds, after flushes that succeeded (stderr through cat: a file
# under the limit would fail too)
port=$(( 40000 + $$ % 20000 ))
# the limit in bytes (ulimit -f counts 512-byte blocks in dash, KiB in bash)
(ulimit -f 120; exec head -c 1000000 /dev/zero >limit.bin) 2>/dev/null
limit=$(wc -c <limit.bin)
rm -f limit.bin
{ (ulimit -f 120; exec timeout 30 "$FTM_SERVER" --scene default $common --rate "$rate" \
      --duration 8 --record f.rec --report f.json --metrics-port $port); echo $? >f.rc; } 2>&1 |
    cat >f.err &
wait_for f.err "session 'srv-recfail" "server did not start (fsize)"
timeout 60 "$FTM_BOT" --role trainee --script "$here/press-hold.bot" $common --id 12 \
    --duration 20 >bot2.out 2>bot2.err &
bot=$!
# the metrics once the recording has stopped (the session goes on), until
# the server has ended
timeout 60 python3 - $port >fm.out 2>&1 <<'EOF' &
import os, sys, time, urllib.request
url = "http://127.0.0.1:%s/metrics" % sys.argv[1]
last = "no scrape answered"
while not os.path.exists("f.rc"):
    time.sleep(0.1)
    try:
        with urllib.request.urlopen(url, timeout=5) as r:
            text = r.read().decode()
    except OSError as e:
        last = str(e)
        continue
    v = dict(l.rsplit(" ", 1) for l in text.splitlines() if l and not l.startswith("#"))
    last = "ftm_record_ok %s" % v.get("ftm_record_ok")
    if v.get("ftm_record_ok") == "0":
        print("ok", v["ftm_record_ok"], "errors", v["ftm_record_errors_total"],
              "bytes", v["ftm_record_bytes"], flush=True)
        sys.exit(0)
print("ftm_record_ok never 0 while the server ran; last:", last, flush=True)
sys.exit(1)
EOF
scraper=$!
wait $scraper || fail "metrics: $(cat fm.out)"
wait
rc=$(cat f.rc)
[ "$rc" -eq 3 ] || fail "under a file size limit: status $rc, not 3 (153: killed by SIGXFSZ)"
grep -q "error: recording f.rec: write failed: File too large; recording stopped for good at tick [0-9]* ([0-9.]* s): the file keeps [0-9]* bytes, replayable to tick [0-9]*; it does not resume" f.err ||
    fail "no error for the recording"
grep -q "shutting down (duration reached)" f.err || fail "the session did not run to its end"
grep -q "error: recording f.rec incomplete: stopped for good at tick [0-9]* ([0-9.]* s into the session) on a write error: recording f.rec: write failed: File too large; [0-9]* bytes kept, replayable to tick [0-9]*" f.err ||
    fail "the closing lines do not say the recording stopped"
size=$(wc -c <f.rec)
[ "$size" -le "$limit" ] || fail "the recording is over the limit"
# what fitted is kept: >= 90 % of the limit (the entries of the failed
# chunk that fit are kept, each a chunk of its own)
[ $(( size * 10 )) -ge $(( limit * 9 )) ] ||
    fail "the recording kept $size bytes of the $limit allowed (< 90 %)"
grep -q "^ok 0 errors 1 bytes $size\$" fm.out || fail "metrics after the stop: $(cat fm.out), the file $size bytes"
grep -q '"recording":{"ok":false,"stopped_tick":[0-9]*,"stopped_seconds":[0-9.]*,"error":"recording f.rec: write failed: File too large","kept_bytes":'"$size"',"kept_to_tick":[0-9]*,"not_resumed":"the error was not a full disk"}' f.json ||
    fail "the report does not say the recording stopped: $(grep -o '"recording":{[^}]*}' f.json)"
# whole chunks: replayed to there with a note
timeout 30 "$FTM_SERVER" --replay f.rec >fr.out 2>fr.err ||
    fail "the recording stopped by the limit does not replay: $(grep -v info: fr.err | tail -1)"
grep -q "note: the recording ends at entry [0-9]* without the server's final status" fr.err ||
    fail "the replay did not say the recording was cut"
echo "fsize: status 3, $size of $limit bytes kept ($(( size * 1000 / limit )) per mille), replayable"

# report: the previous one stays whole
printf '0 0.035 0.035 0.12\n0.2 0.035 0.035 0.106\n0.4 0.035 0.035 0.12\n' >t.bot
printf '{"previous":true}\n' >r.json
cp r.json r.orig
{ (ulimit -f 0; exec timeout 30 "$FTM_SERVER" --offline 200 --trainee 11:0:t.bot \
      --report r.json); echo $? >r.rc; } 2>&1 | cat >r.err
rc=$(cat r.rc)
[ "$rc" -eq 3 ] || fail "report over the limit: status $rc, not 3"
grep -q "error: report r.json: cannot write: File too large" r.err || fail "no error for the report"
cmp -s r.json r.orig || fail "the previous report was changed: '$(head -c 80 r.json)'"
[ -z "$(ls | grep 'r\.json\.')" ] || fail "a temporary file was left: $(ls | grep 'r\.json\.')"
timeout 30 "$FTM_SERVER" --offline 200 --trainee 11:0:t.bot --report r.json >r2.out 2>r2.err ||
    fail "the report could not replace the previous one"
grep -q '"touches":1,' r.json || fail "the new report has no touch"
# nostart: the port held by a listener of our own
python3 -c 'import socket, time
s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen()
print(s.getsockname()[1], flush=True); time.sleep(30)' >port.txt &
holder=$!
wait_for port.txt "[0-9]" "no port held"
mkdir recs
timeout 30 "$FTM_SERVER" $common --record-dir recs --metrics-port "$(cat port.txt)" \
    --duration 1 >ns.out 2>ns.err
rc=$?
kill $holder 2>/dev/null
[ $rc -eq 3 ] && grep -q "metrics: cannot listen" ns.err || fail "metrics port taken: status $rc"
[ -z "$(ls recs)" ] || fail "a server that did not start left $(ls recs)"
echo "PASS recfail"
