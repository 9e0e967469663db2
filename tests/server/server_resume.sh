#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server --resume (loopback, a DDS domain and session of its own,
# `timeout` around every process but the server that is killed):
#   resume:  a recorded session with two trainee bots pressing, the server
#            SIGKILLed after about 3.5 s at tick T (the bots' last tick from
#            it); once the bots have seen it gone, `--resume` re-runs the
#            recording and goes on at tick T' >= T - 100 with the hash the
#            killed server had at T' (the bots' frame log of the killed
#            server); both bots take it as the lesson resumed (not a new
#            session), resync and end on the server's state; the ids are
#            kept (one report with both trainees, seen before and after);
#            the lesson is two files, l.rec and l.rec.1, which one --replay
#            checks whole, to the resumed server's final tick and hash;
#            the ticks up to the lesson's last keyframe are taken from its
#            frames, only those after it stepped (the log line says which);
#   full:    --resume-full re-runs the whole lesson to the same tick and hash;
#   giveup:  a lesson whose keyframes are too far apart for the fast path is
#            re-run whole, with a note saying why;
#   ended:   that lesson, ended cleanly by the resumed server, is refused by
#            --resume (status 3, saying so);
#   cut:     the killed server's file cut 5 bytes short inside its last
#            chunk (what a crash while writing leaves) resumes from the
#            intact entries before the cut chunk, and the lesson replays
#            past the cut; one bit flipped in a chunk in the middle is
#            refused (damage, not a crash);
#   recent:  --record-dir with --resume-recent (what the systemd unit runs):
#            a lesson that ended is not resumed, a new one begins; the
#            lesson of a server SIGKILLed is resumed into its next file.
set -u
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CONFIG:?}"
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../wait_for.sh"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-resume.XXXXXX")
server=
trap '[ -n "$server" ] && kill $server 2>/dev/null; rm -rf "$dir"' EXIT
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.log "$dir"/*.out "$dir"/*.err; do [ -f "$f" ] && { echo "== $f"; tail -n 15 "$f"; }; done
    exit 1
}
domain=$(( 228 + $$ % 4 )) # as tests/server's other sessions (RUN_SERIAL)
common="--session srv-resume-$$ --domain $domain --config $FTM_CONFIG"
rate=${FTM_TEST_RATE:-200}
cd "$dir" || fail "no $dir"

# resume: the server killed (no `timeout` around it: $! must be it)
"$FTM_SERVER" --scene default $common --rate "$rate" --record l.rec --log a.log >a.out 2>a.err &
server=$!
wait_for a.log "session 'srv-resume" "server did not start"
# their times from the moment each is in the session: on a loaded host a
# bot synced after its scripted press, its probe already below the surface,
# and never touched (docs/bot-script.md, clock session)
{ echo "clock session"; cat "$here/press-hold.bot"; } >p11.bot
{ echo "clock session"; cat "$here/press-hold-b.bot"; } >p12.bot
timeout 60 "$FTM_BOT" --role trainee --script p11.bot $common --id 11 \
    --duration 8 --log b11.csv >b11.out 2>b11.err &
timeout 60 "$FTM_BOT" --role trainee --script p12.bot $common --id 12 \
    --duration 8 --log b12.csv >b12.out 2>b12.err &
wait_for a.log "participant 11 probe 0: contact" "trainee 11 did not touch" 300
wait_for a.log "participant 12 probe 0: contact" "trainee 12 did not touch" 100
sleep 1.8 # about 3.5 s into the session, both pressing
kill -KILL $server
wait $server
server=
cp l.rec k.rec # the killed server's file, for the cut case
# the bots' lease on the killed server expires (2 s); a service restarts it then
wait_for b11.err "server 1 gone" "bot 11 did not see the server gone" 100
wait_for b12.err "server 1 gone" "bot 12 did not see the server gone" 100
timeout 60 "$FTM_SERVER" $common --resume l.rec --duration 3 --log c.log >c.out 2>c.err ||
    fail "--resume failed"
wait # the bots (8 s)
for id in 11 12; do
    grep -q "synced\$" b$id.out || fail "bot $id did not end synced: $(cat b$id.out)"
    grep -q "server 1 resumed the lesson (a new process, going on from tick" b$id.err ||
        fail "bot $id did not take the server as the lesson resumed"
    grep -q "1 server restart rejoined (1 resuming the lesson)" b$id.err ||
        fail "bot $id did not count the resume"
done
line=$(grep "resumed lesson l.rec at tick" c.err) || fail "the server did not say it resumed"
# the fast path: the ticks up to the last keyframe taken from the frames,
# only those after it stepped (fewer than a keyframe interval, 1 s)
! grep -q "the fast resume gives up\|did not reach the lesson's last keyframe" c.err ||
    fail "the fast resume gave up: $(grep 'fast resume' c.err)"
kt=$(echo "$line" | sed -n 's/.* taken from the frames, the tissue from the keyframe of tick \([0-9]*\), ticks \([0-9]*\)\.\.\([0-9]*\) stepped and checked)$/\1 \2 \3/p')
[ -n "$kt" ] || fail "the resume does not say which ticks it stepped: $line"
set -- $kt
[ "$1" -gt 0 ] && [ "$2" -eq $(( $1 + 1 )) ] && [ $(( $3 - $1 )) -le $(( rate + rate / 5 )) ] ||
    fail "stepped ticks $2..$3 after the keyframe of tick $1: not the last second only"
t1=$(echo "$line" | sed 's/.* at tick \([0-9]*\) hash.*/\1/')
h1=$(echo "$line" | sed 's/.* hash \([0-9a-f]*\) .*/\1/')
# T: the newest tick a bot had from the killed server (its resync line)
t0=$(sed -n 's/.*we were at tick \([0-9]*\)): resyncing.*/\1/p' b11.err b12.err | sort -n | tail -1)
[ -n "$t0" ] && [ -n "$t1" ] || fail "no ticks: killed at '$t0', resumed at '$t1'"
[ "$t1" -le "$t0" ] && [ "$t1" -ge $(( t0 - 100 )) ] ||
    fail "resumed at tick $t1, the killed server was at tick $t0 (T - 100 at least)"
# the killed server's frame of tick T' in a bot's log (the first line of
# that tick: the resumed server's frames begin after it)
for id in 11 12; do
    was=$(awk -F, -v t="$t1" '$2 == t { print $3; exit }' b$id.csv)
    [ "$was" = "$h1" ] ||
        fail "tick $t1: the resumed server has hash $h1, the killed one had '$was' (bot $id's log)"
done
[ -s l.rec.1 ] || fail "no l.rec.1: the resumed server did not record on"
grep -q "recording the lesson on to l.rec.1 (its file 2)" c.err || fail "no recording line"
# one report: both trainees, from before the kill to after the resume
[ -s l.json ] || fail "no report l.json beside the lesson"
for id in 11 12; do
    first=$(sed -n 's/.*{"id":'$id',"role":"trainee","name":"trainee","first_tick":\([0-9]*\),"last_tick":\([0-9]*\).*/\1 \2/p' l.json)
    [ -n "$first" ] || fail "the report has no trainee $id"
    set -- $first
    [ "$1" -lt "$t1" ] && [ "$2" -gt "$t1" ] ||
        fail "trainee $id seen from tick $1 to $2 in the report, not across the resume at $t1"
done
[ "$(grep -o '"id":' l.json | wc -l)" -eq 2 ] || fail "the report has other participants: $(cat l.json)"
final=$(sed -n 's/^ftm-server: final tick //p' c.out)
timeout 60 "$FTM_SERVER" --replay l.rec --report r.json >replay.out 2>replay.err ||
    fail "the lesson does not replay: $(tail -2 replay.err)"
grep -q "one lesson in 2 files" replay.out || fail "the replay did not take both files"
[ "$(sed -n 's/^ftm-server: final tick //p' replay.out)" = "$final" ] ||
    fail "the replay ends on $(sed -n 's/^ftm-server: final tick //p' replay.out), the server on $final"
cmp -s l.json r.json || fail "the replay's report differs from the server's"
echo "resume: killed at tick $t0, resumed at tick $t1 (hash $h1, as the killed server had it); final $final; $(sed -n 's/.*(1 file, \(.*\))$/\1/p' c.err)"

# ended: the lesson the resumed server ended is not resumed
timeout 60 "$FTM_SERVER" $common --resume l.rec --duration 1 >e.out 2>e.err
rc=$?
[ "$rc" -eq 3 ] || fail "--resume of an ended lesson: status $rc, not 3"
grep -q "ftm-server --resume: l.rec: the lesson ended cleanly at tick [0-9]* (its server's final status is in l.rec.1): nothing to resume" e.err ||
    fail "no message for an ended lesson: $(cat e.err)"
[ ! -e l.rec.2 ] || fail "an ended lesson got a file l.rec.2"
echo "ended: $(tail -1 e.err)"

# full: --resume-full re-runs the whole killed lesson's physics to the same
# tick and hash as the fast path
cp k.rec full.rec
timeout 60 "$FTM_SERVER" $common --resume full.rec --resume-full --duration 0.3 >f.out 2>f.err ||
    fail "--resume-full failed: $(tail -2 f.err)"
grep -q "resumed lesson full.rec at tick $t1 hash $h1 .* ticks 1\.\.$t1 stepped, --resume-full)" f.err ||
    fail "--resume-full did not go on at tick $t1 hash $h1: $(grep 'resumed lesson' f.err)"
echo "full: $(sed -n 's/.*(1 file, \(.*\))$/\1/p' f.err)"

# giveup: keyframes further apart than the guard's shortest episode (1024
# ticks): the fast path cannot tell the report's unstable ticks, says so
# and re-runs the whole lesson (no trainee: idle ticks, quick)
timeout -s KILL 3 "$FTM_SERVER" $common --rate 1000 --keyframe-every 1.2 --record g.rec \
    >g.out 2>g.err
[ -s g.rec ] || fail "no recording g.rec"
timeout 60 "$FTM_SERVER" $common --resume g.rec --duration 0.2 >gr.out 2>gr.err ||
    fail "--resume of g.rec failed: $(tail -2 gr.err)"
grep -q "the fast resume gives up: keyframes at ticks 0 and 1[0-9]* are more than 1024 ticks apart.*the whole lesson is re-run instead" gr.err ||
    fail "the fast resume did not give up on keyframes 1200 ticks apart: $(grep 'resume' gr.err)"
grep -q "resumed lesson g.rec at tick [0-9]* hash [0-9a-f]* (.* ticks 1\.\.[0-9]* stepped, --resume-full)" gr.err ||
    fail "g.rec was not re-run whole: $(grep 'resumed lesson' gr.err)"
echo "giveup: $(sed -n 's/.*(1 file, \(.*\))$/\1/p' gr.err)"

# cut: k.rec 5 bytes short, then a copy with a bit flipped in a middle chunk
size=$(wc -c <k.rec)
head -c $(( size - 5 )) k.rec >cut.rec
timeout 60 "$FTM_SERVER" $common --resume cut.rec --duration 0.5 >cut.out 2>cut.err ||
    fail "--resume of a file cut short failed: $(tail -2 cut.err)"
grep -q "ftm-server --resume: note: cut.rec: truncated: chunk [0-9]* .*; re-running the lesson up to entry [0-9]* before it (what the crash cut)" cut.err ||
    fail "no note on the cut chunk"
tc=$(sed -n 's/.*resumed lesson cut.rec at tick \([0-9]*\) hash.*/\1/p' cut.err)
[ -n "$tc" ] && [ "$tc" -le "$t1" ] && [ "$tc" -ge $(( t1 - 100 )) ] ||
    fail "the cut file resumed at tick '$tc' (the whole one at $t1)"
timeout 60 "$FTM_SERVER" --replay cut.rec >cr.out 2>cr.err ||
    fail "the cut lesson does not replay: $(tail -2 cr.err)"
grep -q "1 crash cut passed over" cr.out || fail "the replay did not pass over the cut"
python3 - <<'EOF' || fail "cannot flip a bit"
data = bytearray(open("k.rec", "rb").read())
data[len(data) // 2] ^= 0x10
open("flip.rec", "wb").write(data)
EOF
timeout 60 "$FTM_SERVER" $common --resume flip.rec --duration 0.5 >flip.out 2>flip.err
rc=$?
[ "$rc" -eq 3 ] || fail "--resume of a damaged file: status $rc, not 3"
grep -q "damaged: .* (not the end of the lesson's last file, where a crash cuts it: not resumed" flip.err ||
    fail "no message for the damage: $(tail -2 flip.err)"
[ ! -e flip.rec.1 ] || fail "a damaged lesson was recorded on"
echo "cut: resumed at tick $tc; a flipped bit refused: $(grep -o 'damaged: [^(]*' flip.err | head -1)"

# recent: --record-dir with --resume-recent (the service's way): a lesson
# that ended is not resumed (a new one begins), one whose server was killed
# is; the files stay in the directory, one lesson per first file
mkdir rd
timeout 60 "$FTM_SERVER" $common --rate "$rate" --record-dir rd --duration 0.5 >r1.out 2>r1.err ||
    fail "a recorded session in rd failed"
timeout 60 "$FTM_SERVER" $common --rate "$rate" --record-dir rd --resume-recent 60 \
    --duration 0.5 >r2.out 2>r2.err || fail "--resume-recent after an ended lesson failed"
grep -q "resume-recent: the newest lesson rd/srv-resume-$$-[0-9TZ-]*.rec ended cleanly: a new lesson" r2.err ||
    fail "--resume-recent did not say the newest lesson ended"
"$FTM_SERVER" $common --rate "$rate" --record-dir rd --log r3.log >r3.out 2>r3.err &
server=$!
wait_for r3.log "session 'srv-resume" "server did not start (record-dir)"
sleep 1 # a few heartbeat frames on the disk
kill -KILL $server
wait $server
server=
killed=$(ls -t rd/*.rec | head -1)
timeout 60 "$FTM_SERVER" $common --rate "$rate" --record-dir rd --resume-recent 60 \
    --duration 0.5 >r4.out 2>r4.err || fail "--resume-recent after a killed server failed"
grep -q "resume-recent: the newest lesson $killed did not end (last written [0-9.]* s ago): resuming it" r4.err ||
    fail "--resume-recent did not resume $killed"
grep -q "resumed lesson $killed at tick" r4.err || fail "the killed lesson was not resumed"
[ -s "$killed.1" ] || fail "no $killed.1"
[ "$(ls rd/*.rec | wc -l)" -eq 3 ] || fail "rd has $(ls rd/*.rec | wc -l) lessons, not 3"
timeout 60 "$FTM_SERVER" --replay "$killed" >rr.out 2>rr.err || fail "the resumed lesson in rd does not replay"
echo "recent: an ended lesson not resumed; $killed resumed at tick $(sed -n 's/.*resumed lesson .* at tick \([0-9]*\) hash.*/\1/p' r4.err)"
echo "PASS"
