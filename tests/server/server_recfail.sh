#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server's recording and report when things go wrong (loopback, a DDS
# domain and session of its own, `timeout` around every process):
#   killed:  a session with a pressing trainee, the server SIGKILLed after
#            about 2.5 s: the recording has reached the file (flushed every
#            0.5 s, not only per MiB), replays with every hash equal and a
#            note that it was cut, and its report has the trainee's touch;
#   fsize:   a session under a file size limit (ulimit -f) smaller than its
#            recording: the write fails (EFBIG), the recording stops with a
#            logged error, the session goes on to its end and the server
#            exits 3 — not killed by SIGXFSZ; the file is cut back to its
#            last flush and replays to there;
#   report:  a report that cannot be written (ulimit -f 0) leaves the
#            previous file as it was and no temporary file; status 3;
#   nostart: a server that cannot start (its metrics port taken) leaves
#            no recording in its --record-dir.
set -u
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}"
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-recfail.XXXXXX")
trap 'rm -rf "$dir"' EXIT
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

# fsize: 150 KiB allowed, which the trainee's joining and press pass within
# a few seconds, after flushes that succeeded (stderr through cat: a file
# under the limit would fail too)
{ (ulimit -f 150; exec timeout 30 "$FTM_SERVER" --scene default $common --rate "$rate" \
      --duration 6 --record f.rec); echo $? >f.rc; } 2>&1 | cat >f.err &
wait_for f.err "session 'srv-recfail" "server did not start (fsize)"
timeout 60 "$FTM_BOT" --role trainee --script "$here/press-hold.bot" $common --id 12 \
    --duration 20 >bot2.out 2>bot2.err &
bot=$!
wait
rc=$(cat f.rc)
[ "$rc" -eq 3 ] || fail "under a file size limit: status $rc, not 3 (153: killed by SIGXFSZ)"
grep -q "error: recording f.rec: write failed: File too large; recording stopped" f.err ||
    fail "no error for the recording"
grep -q "shutting down (duration reached)" f.err || fail "the session did not run to its end"
[ "$(wc -c <f.rec)" -le 153600 ] || fail "the recording is over the limit"
# cut back to its last flush: whole entries, replayed to there with a note
timeout 30 "$FTM_SERVER" --replay f.rec >fr.out 2>fr.err ||
    fail "the recording stopped by the limit does not replay: $(grep -v info: fr.err | tail -1)"
grep -q "note: the recording ends at entry [0-9]* without the server's final status" fr.err ||
    fail "the replay did not say the recording was cut"
echo "fsize: status 3, $(wc -c <f.rec) bytes recorded"

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
