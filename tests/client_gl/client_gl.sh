#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-client under Xvfb with Mesa's software renderer, against a real
# ftm-server on loopback (its own DDS domain and session, like tests/net).
#   screenshot: an undeformed frame (no trainee yet), then a scripted trainee
#       (ftm-bot, hold.bot) presses into the tissue and a deformed frame is
#       taken once the contact has lasted 200 ticks; client-png-check
#       asserts the pixels around the contact changed and neither is blank,
#       and that the trainee's instrument (its steel shaft) is drawn.
#   instructor: an instructor client's timed commands (--commands) change
#       the stiffness and the depth limits; server and client apply them;
#       a trainee bot presses meanwhile, and the instructor's debriefing
#       figures (peak force and its tick) are those of the bot's frames.
#   badinput: a scene the client cannot load, malformed tick frames, its
#       participant id already taken by another process, and a server that
#       vanishes (SIGKILL): each time the client logs it, shows the red
#       banner (checked in its screenshot) and keeps running. Then a
#       server restarted (a new process on the session): the client rejoins;
#       and restarted with another scene: the client loads and draws it.
#   volume: the built-in `head` scene (a head phantom embedded in a 10x10x10
#       control lattice, paper 4.2): the client draws the volume (the middle
#       of the view drawn, the corners background; unlike its --no-volume
#       surface); the default (a slice per plane, drawn at a lower
#       resolution and scaled up) draws what the same slices draw at the
#       window's resolution (--volume-scale 16), and a slice per 10 planes
#       (key n) the default's picture (no banding); once a scripted trainee
#       (head.bot) has pressed the top, the pixels around the contact
#       changed, and the window's resolution and a slice per 5 planes draw
#       the dent as the default does; cut away (--cut, key x) it shows
#       something other than the whole volume.
#   reset: a trainee's mouse probe (xdotool) pressed into the tissue,
#       the camera orbited, the wheel back out: the contact releases in
#       about as many notches as went in, the reaction along the normal;
#       pressed again, the instructor's reset: the client moves the probe out, more wheel
#       notches touch the tissue again, key u lifts the probe; a trainee's
#       instructor key is answered on screen; F1 shows the help overlay.
#       Skipped (77) without xdotool.
#   tissues: a block of two labelled tissues (tests/data/two_tissue.msh):
#       each tissue is drawn in
#       its own colour (not the other's, not the unlabelled one) where the
#       client says it sees it, and the legend shows both swatches below
#       the HUD's rows.
#   volumelabels: a volume and its label map ([volume] labels), both
#       written here: each labelled half of the block is drawn in its
#       tissue's colour (the surface's palette, label 15 as label 5); the
#       same volume without the key in the intensity's colours; cut away
#       (--cut), the section shows both tissues' colours.
#   fps: --max-fps 20 draws 10..24 fps over 3 s under Xvfb (where the swap
#       interval does not throttle), the default cap at most 72 fps.
# Exit 77 (skipped) without xvfb-run/Xvfb. Every process runs under timeout.
set -u
mode=${1:?mode}
. "$(cd "$(dirname "$0")" && pwd)/../wait_for.sh"
: "${FTM_SERVER:?}" "${FTM_BOT:?}" "${FTM_CLIENT:?}" "${FTM_PNG_CHECK:?}" "${FTM_CONFIG:?}"
: "${FTM_DATA:?}"
if ! command -v xvfb-run >/dev/null 2>&1 || ! command -v Xvfb >/dev/null 2>&1; then
    echo "SKIP: xvfb-run or Xvfb not installed"
    exit 77
fi
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-client-gl-$mode.XXXXXX")
trap 'kill $server 2>/dev/null; rm -rf "$dir"' EXIT
server=
domain=$(( 220 + $$ % 10 ))   # tests/net use 1..97, tests/wire 100..219
session="client-gl-$mode-$$"
common="--session $session --domain $domain --config $FTM_CONFIG"
export LIBGL_ALWAYS_SOFTWARE=1
fail() { echo "FAIL: $*"; for f in "$dir"/*.out "$dir"/*.err "$dir"/*.log; do [ -f "$f" ] && { echo "== $f"; tail -n 30 "$f"; }; done; exit 1; }
# Under ASan, LeakSanitizer is off for ftm-client only: Mesa's llvmpipe
# driver leaves allocations at exit from code it has already unloaded, which
# LSan reports without a module to suppress by. The client's own logic is
# leak-checked by its unit tests (test_haptic*, test_replay); the server and
# bots here still run with leak detection.
client_asan=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0
# The X authority file lives in $dir: left to make its own temporary
# directory, xvfb-run once failed to remove it (under the ASan suite's load)
# and exited 5 in place of the client's status.
client() { # name, then client options
    n=$1; shift
    : >"$dir/$n.xauth"
    ASAN_OPTIONS=$client_asan timeout 90 xvfb-run -a -f "$dir/$n.xauth" -s "-screen 0 1280x800x24" \
        "$FTM_CLIENT" $common --size "${size:-960x600}" --log "$dir/$n.log" "$@" >"$dir/$n.out" 2>"$dir/$n.err"
}
start_server() { # extra server options...
    # no `timeout` wrapper: $server must be the server itself (SIGKILL below);
    # --duration bounds it and the EXIT trap kills it
    "$FTM_SERVER" --scene default $common --rate "${FTM_TEST_RATE:-500}" --duration 80 \
        --log "$dir/server.log" "$@" >"$dir/server.out" 2>"$dir/server.err" &
    server=$!
    wait_for "$dir/server.log" "session '$session'" "server did not start"
}

case $mode in
screenshot)
    start_server
    # the colour map on (off by default: the tissue's own colour) makes the
    # dent's pixels change by more than shading alone
    client before --colormap --screenshot "$dir/before.png" --screenshot-timeout 40 ||
        fail "client (undeformed) exited with $?"
    grep -q "contact none" "$dir/before.out" || fail "a contact before any trainee joined?"
    timeout 100 "$FTM_BOT" --role trainee --script "$FTM_DATA/hold.bot" $common --id 11 \
        --duration 80 >"$dir/bot.out" 2>"$dir/bot.err" &
    client after --colormap --screenshot "$dir/after.png" --screenshot-contact 200 --screenshot-timeout 60 ||
        fail "client (deformed) exited with $?"
    set -- $(sed -n 's/^screenshot .* view-top \([0-9]*\) .*contact \([0-9]*\) \([0-9]*\)$/\2 \3 \1/p' \
        "$dir/after.out")
    [ $# -eq 3 ] || fail "no contact pixel or view top in the client's screenshot line"
    # the view is framed below the HUD: the contact is not drawn under it
    [ "$3" -gt 0 ] && [ "$2" -gt "$3" ] || fail "contact at row $2, under the HUD (rows 0..$3)"
    "$FTM_PNG_CHECK" compare "$dir/before.png" "$dir/after.png" "$1" "$2" 40 || fail "png check"
    grep -q "synced at tick" "$dir/after.log" || fail "client never synced"
    # the trainee's instrument: its steel shaft drawn where the client says
    set -- $(sed -n 's/^screenshot .* shaft \([0-9]*\) \([0-9]*\) contact .*/\1 \2/p' "$dir/after.out")
    [ $# -eq 2 ] || fail "no shaft pixel in the client's screenshot line"
    "$FTM_PNG_CHECK" steel "$dir/after.png" "$1" "$2" 2 || fail "png check: no instrument drawn"
    # its name label at the shaft's top, in trainee 11's colour (render.c:
    # green, the same in every view): to the right of the shaft's top, or
    # down the shaft to just below the HUD when the top is under it
    set -- $(sed -n 's/^screenshot .* view-top \([0-9]*\) label \([0-9]*\) \([0-9]*\) shaft .*/\1 \2 \3/p' \
        "$dir/after.out")
    [ $# -eq 3 ] || fail "no label point in the client's screenshot line"
    y1=$(( $3 > $1 + 30 ? $3 : $1 + 30 ))
    "$FTM_PNG_CHECK" hue "$dir/after.png" "$(($2 + 4))" "$(($3 - 24))" "$(($2 + 140))" "$y1" \
        0.20 0.90 0.35 || fail "png check: no name label in the trainee's colour"
    # a mesh without labels: its own tissue colour, no legend
    ! grep -q '^legend' "$dir/after.out" || fail "a legend for a mesh without labels"
    [ -n "${FTM_KEEP_SCREENSHOT:-}" ] && cp "$dir/after.png" "$FTM_KEEP_SCREENSHOT"
    echo "PASS screenshot: $(cat "$dir/after.out")"
    ;;
tissues)
    # a mesh of two labelled tissues (tests/data/two_tissue.msh: physical
    # groups 1 and 2 side by side, named by the scene's [fem LABEL] name):
    # each drawn in its own colour, where the client says it sees it, and
    # the legend with both colours' swatches, below the HUD's rows
    # (no trainee: an instrument would hide the tissue behind it; the
    # docs' picture, docs/client.md, has one pressing)
    start_server --scene "$FTM_DATA/../data/scenes/two_tissue.scene"
    client tis --role observer --screenshot "$dir/tis.png" --screenshot-timeout 40 ||
        fail "client exited with $?"
    grep -q "tissue: label 1, grey matter  E 2 kPa, 136 surface triangles" "$dir/tis.log" &&
        grep -q "tissue: label 2, white matter  E 6 kPa, 136 surface triangles" "$dir/tis.log" ||
        fail "the client's log does not list both tissues"
    top=$(sed -n 's/^screenshot .* view-top \([0-9]*\) .*/\1/p' "$dir/tis.out")
    set -- $(sed -n 's/^legend //p' "$dir/tis.out")
    [ $# -eq 4 ] && [ -n "$top" ] || fail "no legend or view top in the client's output"
    [ "$2" -gt "$top" ] || fail "the legend (rows $2..$4) reaches into the HUD's rows (0..$top)"
    c1="0.80 0.36 0.40" c2="0.93 0.86 0.66" c0="0.86 0.56 0.52" # tissues.c: labels 1, 2, 0
    for c in "$c1" "$c2"; do
        "$FTM_PNG_CHECK" hue "$dir/tis.png" "$1" "$2" "$3" "$4" $c ||
            fail "png check: no swatch of ($c) in the legend"
    done
    # most of a small box around the point in the tissue's colour (by
    # chromaticity: shading keeps it, a highlight or a neighbour's edge may
    # not), little of it in the other's or the unlabelled colour
    share() { # colour -> percent of the box's pixels of that colour
        "$FTM_PNG_CHECK" hue "$dir/tis.png" $box "$@" |
            sed -n 's/.*: \([0-9]*\) of \([0-9]*\) pixels of colour.*/\1 \2/p' |
            awk '{ print int(100 * $1 / $2) }'
    }
    for label in 1 2; do
        set -- $(sed -n "s/^tissue $label \([0-9]*\) \([0-9]*\) .*/\1 \2/p" "$dir/tis.out")
        [ $# -eq 2 ] || fail "tissue $label not in sight"
        box="$(($1 - 6)) $(($2 - 6)) $(($1 + 6)) $(($2 + 6))"
        if [ $label = 1 ]; then own=$c1 other=$c2; else own=$c2 other=$c1; fi
        p=$(share $own)
        [ "${p:-0}" -ge 60 ] || fail "png check: tissue $label: ${p:-0} % of ($box) in its colour ($own)"
        for c in "$other" "$c0"; do
            p=$(share $c)
            [ "${p:-100}" -le 20 ] || fail "png check: tissue $label: ${p:-?} % of ($box) in ($c)"
        done
    done
    [ -n "${FTM_KEEP_SCREENSHOT:-}" ] && cp "$dir/tis.png" "$FTM_KEEP_SCREENSHOT"
    echo "PASS tissues: $(cat "$dir/tis.out")"
    ;;
instructor)
    # the GL client as instructor plays timed commands (--commands): the
    # server applies the stiffness and the depth limits, the client's own
    # replica switches its tissue at the frame that carries it
    # A trainee bot presses from about 3 s to 5.5 s, when it leaves: the
    # instructor's debriefing figures (HUD, closing log) must be those of
    # the frames the trainee received.
    start_server
    timeout 60 "$FTM_BOT" --role trainee --script "$FTM_DATA/hold.bot" $common --id 11 \
        --duration 5.5 --log "$dir/bot11.csv" >"$dir/bot.out" 2>"$dir/bot.err" &
    bpid=$!
    # (in a 640 px window: the instructor's HUD, the widest, wraps and fits)
    size=640x480 client instr --role instructor --id 21 --commands "$FTM_DATA/instructor.cmds" \
        --screenshot "$dir/instr.png" --screenshot-after 7 || fail "instructor client exited with $?"
    top=$(sed -n 's/^screenshot .* view-top \([0-9]*\) .*/\1/p' "$dir/instr.out")
    [ -n "$top" ] || fail "no view top in the instructor's screenshot line"
    "$FTM_PNG_CHECK" hudfit "$dir/instr.png" "$top" ||
        fail "png check: the instructor's HUD is cut off at 640 px"
    wait $bpid || fail "trainee bot exited with $?"
    grep -q "tissue from tick [0-9]* (instructor 21): stiffness 100 N/m (was 50)" "$dir/server.log" ||
        fail "the server did not apply the instructor's stiffness"
    grep -q "depth limits \[2, 6\] from instructor 21" "$dir/server.log" ||
        fail "the server did not apply the instructor's depth limits"
    grep -q "sent stiffness (k = 100 N/m" "$dir/instr.log" || fail "the client did not send it"
    grep -q "tissue now k 100 N/m" "$dir/instr.log" || fail "the client's replica did not switch"
    # the server's replies, as the HUD shows them for a few seconds
    grep -q "command stiffness 100 N/m: applied after tick [0-9]" "$dir/instr.log" ||
        fail "the client did not report the server's reply to the stiffness"
    grep -q "command depth limits 2..6: applied after tick [0-9]*: depth now" "$dir/instr.log" ||
        fail "the client did not report the server's reply to the depth limits"
    line=$(grep "participant 11 probe 0, from the frames received" "$dir/instr.log") ||
        fail "no debriefing line for trainee 11 in the instructor's log"
    debrief=$(timeout 30 python3 - "$dir/bot11.csv" "$line" <<'EOF'
import csv, math, re, sys
m = re.search(r"([0-9.]+) s in contact, peak ([0-9.eE+-]+) N at tick ([0-9]+)", sys.argv[2])
secs, peak, tick = float(m.group(1)), float(m.group(2)), int(m.group(3))
rows = {int(r["tick"]): math.sqrt(float(r["fx"])**2 + float(r["fy"])**2 + float(r["fz"])**2)
        for r in csv.DictReader(open(sys.argv[1]))}
assert secs > 0.5, sys.argv[2]
assert abs(rows[tick] - peak) <= 1e-8 * peak, (rows[tick], peak)
assert max(rows.values()) <= peak * (1 + 1e-8), (max(rows.values()), peak)
print("peak %.4g N at tick %d, %.2f s in contact" % (peak, tick, secs))
EOF
) || fail "instructor's debriefing: $debrief"
    echo "PASS instructor: $(grep -o 'tissue from tick [0-9]*' "$dir/server.log"); trainee 11 as the instructor saw it: $debrief"
    ;;
badinput)
    # 1. a scene the client cannot load: banner, log, no crash; exit 1 after the timeout
    start_server
    client noscene --scene "$dir/missing.scene" --screenshot "$dir/noscene.png" \
        --screenshot-timeout 4
    rc=$?
    [ $rc -eq 1 ] || fail "client without its scene exited with $rc, expected 1"
    grep -q "cannot load scene '$dir/missing.scene'" "$dir/noscene.log" || fail "no scene error logged"
    "$FTM_PNG_CHECK" banner "$dir/noscene.png" || fail "no banner for the missing scene"

    # 2. malformed tick frames: logged, banner, the client keeps running and stays in step
    client badframe --screenshot "$dir/badframe.png" --screenshot-after 5 &
    cpid=$!
    timeout 30 "$FTM_BADFRAME" $common --id 66 >"$dir/badframe-pub.out" 2>"$dir/badframe-pub.err" ||
        fail "client-badframe could not send"
    wait $cpid; rc=$?
    [ $rc -eq 0 ] || fail "client exited with $rc after malformed frames"
    grep -q "malformed tick frame rejected" "$dir/badframe.log" || fail "malformed frame not logged"
    "$FTM_PNG_CHECK" banner "$dir/badframe.png" || fail "no banner for the malformed frames"

    # 3a. another process already has the client's participant id: the
    # client says its id is taken (the server ignores it), banner, runs on
    timeout 60 "$FTM_BOT" --role observer $common --id 77 --duration 30 \
        >"$dir/idbot.out" 2>"$dir/idbot.err" &
    idbot=$!
    # (the server's "synced": the bot's statuses say JOINING for its first
    # second, and a client hearing that first takes the bot for the newcomer)
    wait_for "$dir/server.log" "participant 77 .*: synced" "the bot holding id 77 did not sync" 300
    client idtaken --id 77 --screenshot "$dir/idtaken.png" --screenshot-after 4
    rc=$?
    [ $rc -eq 0 ] || fail "client with a taken id exited with $rc"
    grep -q "participant id 77 is taken" "$dir/idtaken.log" || fail "taken id not logged"
    "$FTM_PNG_CHECK" banner "$dir/idtaken.png" || fail "no banner for the taken id"
    kill $idbot 2>/dev/null
    wait $idbot 2>/dev/null

    # 3. the server vanishes (SIGKILL, no LEAVING): the client notices the silence
    client vanish --server-timeout 1 --screenshot "$dir/vanish.png" --screenshot-after 6 &
    cpid=$!
    wait_for "$dir/vanish.log" "synced at tick" "client did not sync before the kill" 300
    kill -KILL $server
    wait $cpid; rc=$?
    [ $rc -eq 0 ] || fail "client exited with $rc after the server vanished"
    grep -q "no tick frames from the server" "$dir/vanish.log" || fail "silence not logged"
    "$FTM_PNG_CHECK" banner "$dir/vanish.png" || fail "no banner for the vanished server"
    [ -n "${FTM_KEEP_SCREENSHOT:-}" ] && cp "$dir/vanish.png" "$dir/noscene.png" "$(dirname "$FTM_KEEP_SCREENSHOT")/"

    # 4. the server is restarted (SIGTERM, then a new process on the same
    # session, as its service restarts it): the client rejoins the new one
    rm -f "$dir/server.log"
    start_server
    client restart --screenshot "$dir/restart.png" --screenshot-after 8 &
    cpid=$!
    wait_for "$dir/restart.log" "synced at tick" "client did not sync before the restart" 300
    kill -TERM $server
    wait $server
    rm -f "$dir/server.log"
    start_server
    # (the session may go from JOINING to synced between two of its looks,
    # so the replica's own line is the one to look for)
    wait_for "$dir/restart.log" "server 1 restarted (a new process" "restart not noticed" 300
    i=0
    until awk '/server 1 restarted/ { r = 1 } r && /replay: synced from keyframe/ { ok = 1 }
               END { exit !ok }' "$dir/restart.log"; do
        i=$((i + 1)); [ $i -gt 300 ] && fail "the client did not sync again with the new server"
        sleep 0.05
    done
    # and once more, the new server with another scene: the client loads it
    kill -TERM $server
    wait $server
    rm -f "$dir/server.log"
    start_server --scene membrane
    wait $cpid; rc=$?
    [ $rc -eq 0 ] || fail "client exited with $rc after the server restarted"
    grep -q "the restarted server has another scene: 'membrane'" "$dir/restart.log" ||
        fail "the client did not notice the new scene"
    awk '/another scene/ { r = 1 } r && /replay: synced from keyframe/ { ok = 1 }
         END { exit !ok }' "$dir/restart.log" || fail "the client did not sync on the new scene"
    grep -q "screenshot .* tick [0-9]*, contact none" "$dir/restart.log" || fail "no screenshot"
    echo "PASS badinput"
    ;;
volume)
    start_server --scene head
    client before --screenshot "$dir/before.png" --screenshot-timeout 40 ||
        fail "client (undeformed) exited with $?"
    grep -q "drawing the scene's volume" "$dir/before.log" || fail "the client drew no volume"
    client surface --no-volume --screenshot "$dir/surface.png" --screenshot-timeout 40 ||
        fail "client (surface) exited with $?"
    # the view's middle: the target (the head's centre) is drawn at the
    # centre of the rows below the HUD
    set -- $(sed -n 's/^screenshot .* \([0-9]*\)x\([0-9]*\) tick .* view-top \([0-9]*\) .*/\1 \2 \3/p' \
        "$dir/before.out")
    [ $# -eq 3 ] || fail "no size or view top in the client's screenshot line"
    cx=$(( $1 / 2 )) cy=$(( $3 + ($2 - $3) / 2 ))
    "$FTM_PNG_CHECK" drawn "$dir/before.png" $cx $cy 60 || fail "png check: volume not drawn"
    "$FTM_PNG_CHECK" compare "$dir/surface.png" "$dir/before.png" $cx $cy 60 ||
        fail "png check: the volume looks like the surface"
    # the default (a slice per plane, drawn at 1.5 pixels per voxel and
    # scaled up) against the same slices at the window's resolution
    # (--volume-scale 16): the same picture, a little softer
    client ref --volume-scale 16 --screenshot "$dir/ref.png" --screenshot-timeout 40 ||
        fail "client (--volume-scale 16) exited with $?"
    "$FTM_PNG_CHECK" similar "$dir/ref.png" "$dir/before.png" $cx $cy 60 4 ||
        fail "png check: the scaled-up slices do not draw the window-resolution picture"
    # a slice per 10 planes (key n): each slice samples the planes it stands
    # for, so the picture is the default's, with no banding
    client coarse --volume-step 10 --screenshot "$dir/coarse.png" --screenshot-timeout 40 ||
        fail "client (--volume-step 10) exited with $?"
    "$FTM_PNG_CHECK" similar "$dir/before.png" "$dir/coarse.png" $cx $cy 60 6 ||
        fail "png check: a slice per 10 planes does not draw what all planes draw"
    timeout 100 "$FTM_BOT" --role trainee --script "$FTM_DATA/head.bot" $common --id 11 \
        --duration 80 >"$dir/bot.out" 2>"$dir/bot.err" &
    # both deformed pictures once the press has settled (head.bot holds its
    # probe still from 3.5 s, the contact starts about 0.5 s before): at 200
    # ticks of contact the probe was still going in, and the later client
    # showed a deeper dent (2.2 % of the pixels differing by more than 24)
    settled=$(( ${FTM_TEST_RATE:-500} * 5 / 2 ))
    client after --screenshot "$dir/after.png" --screenshot-contact $settled --screenshot-timeout 60 ||
        fail "client (deformed) exited with $?"
    set -- $(sed -n 's/^screenshot .* contact \([0-9]*\) \([0-9]*\)$/\1 \2/p' "$dir/after.out")
    [ $# -eq 2 ] || fail "no contact pixel in the client's screenshot line"
    "$FTM_PNG_CHECK" compare "$dir/before.png" "$dir/after.png" "$1" "$2" 40 ||
        fail "png check: the volume did not change at the contact"
    # deformed too: at the window's resolution, and a slice per 5 planes
    # (sampling through the deformation's Jacobian)
    client afterref --volume-scale 16 --screenshot "$dir/afterref.png" \
        --screenshot-contact $settled --screenshot-timeout 60 ||
        fail "client (deformed, --volume-scale 16) exited with $?"
    "$FTM_PNG_CHECK" similar "$dir/afterref.png" "$dir/after.png" "$1" "$2" 60 4 ||
        fail "png check: the scaled-up slices do not draw the dent as the window's resolution does"
    client after5 --volume-step 5 --screenshot "$dir/after5.png" --screenshot-contact $settled \
        --screenshot-timeout 60 || fail "client (deformed, --volume-step 5) exited with $?"
    "$FTM_PNG_CHECK" similar "$dir/after.png" "$dir/after5.png" "$1" "$2" 60 6 ||
        fail "png check: a slice per 5 planes does not draw the dent as all planes do"
    # the cut-away (key x): the section through the middle, not the outside
    client cut --cut --screenshot "$dir/cut.png" --screenshot-contact 200 \
        --screenshot-timeout 60 || fail "client (cut away) exited with $?"
    "$FTM_PNG_CHECK" drawn "$dir/cut.png" $cx $cy 60 || fail "png check: cut-away not drawn"
    "$FTM_PNG_CHECK" compare "$dir/after.png" "$dir/cut.png" $cx $cy 60 ||
        fail "png check: the cut-away looks like the whole volume"
    [ -n "${FTM_KEEP_SCREENSHOT:-}" ] && cp "$dir/after.png" "$FTM_KEEP_SCREENSHOT"
    echo "PASS volume: $(cat "$dir/after.out")"
    ;;
volumelabels)
    # a volume with a label map ([volume] labels): a block of tissue (a
    # bright shell around a softer inside) whose half x < 20 is label 1 and
    # the rest label 15, written here; the client colours each half by its
    # tissue (the surface's palette: 1 rose, 15 the 5th colour, bluish),
    # and the same volume without the key keeps the intensity's colours
    timeout 30 python3 - "$dir/vol.nii" "$dir/lab.nii" <<'EOF'
import struct, sys
def nii(path, n, mm, dtype, bitpix, fmt, vals):
    h = bytearray(352)
    struct.pack_into('<i', h, 0, 348)
    struct.pack_into('<8h', h, 40, 3, n, n, n, 1, 1, 1, 1)
    struct.pack_into('<hh', h, 70, dtype, bitpix)
    struct.pack_into('<8f', h, 76, 1, mm, mm, mm, 0, 0, 0, 0)
    struct.pack_into('<f', h, 108, 352)
    struct.pack_into('<f', h, 112, 1)
    h[123] = 2  # mm
    h[344:348] = b'n+1\0'
    with open(path, 'wb') as f:
        f.write(h)
        f.write(struct.pack('<%d%s' % (len(vals), fmt), *vals))
n = 40
vol, lab = [], []
for k in range(n):
    for j in range(n):
        for i in range(n):
            inside = all(6 <= a < 34 for a in (i, j, k))
            shell = inside and any(a < 8 or a >= 32 for a in (i, j, k))
            vol.append(255 if shell else 140 if inside else 0)
            lab.append(0 if not inside else 1 if i < 20 else 15)
nii(sys.argv[1], n, 2.5, 2, 8, 'B', vol)
nii(sys.argv[2], n, 2.5, 4, 16, 'h', lab)
EOF
    [ $? -eq 0 ] || fail "could not write the volume and its label map"
    for s in labelled unlabelled; do
        { echo "[scene]"; echo "name = $s"; echo "[mesh]"; echo "generator = volume"
          echo "[volume]"; echo "file = vol.nii"; [ $s = labelled ] && echo "labels = lab.nii"
          echo "nodes = 5"; echo "fix = zmin"
          echo "[material]"; echo "mass = 0.01"; echo "damping = 1"; echo "stiffness = 250"
          echo "[sim]"; echo "time_step = 1e-3"; echo "depth = 8"; } >"$dir/$s.scene"
    done
    start_server --scene "$dir/labelled.scene"
    client lab --role observer --screenshot "$dir/lab.png" --screenshot-timeout 40 ||
        fail "client exited with $?"
    grep -q "drawing the scene's volume (40x40x40 voxels) as slices, coloured by its label map" \
        "$dir/lab.log" || fail "the client did not draw the volume by its label map"
    # cut away (key x): the section through the middle, opaque, both tissues
    client labcut --role observer --cut --screenshot "$dir/labcut.png" --screenshot-timeout 40 ||
        fail "client (cut away) exited with $?"
    kill $server 2>/dev/null; wait $server 2>/dev/null
    rm -f "$dir/server.log"
    start_server --scene "$dir/unlabelled.scene"
    client nolab --role observer --screenshot "$dir/nolab.png" --screenshot-timeout 40 ||
        fail "client (no label map) exited with $?"
    ! grep -q "coloured by its label map" "$dir/nolab.log" || fail "a label map where none is"
    # the view's middle is the block's centre; x < 20 is drawn left of it
    set -- $(sed -n 's/^screenshot .* \([0-9]*\)x\([0-9]*\) tick .* view-top \([0-9]*\) .*/\1 \2 \3/p' \
        "$dir/lab.out")
    [ $# -eq 3 ] || fail "no size or view top in the client's screenshot line"
    cx=$(( $1 / 2 )) cy=$(( $3 + ($2 - $3) / 2 ))
    left="$((cx - 100)) $((cy - 40)) $((cx - 50)) $((cy + 40))"
    right="$((cx + 30)) $((cy - 40)) $((cx + 100)) $((cy + 40))"
    c1="0.80 0.36 0.40" c15="0.60 0.72 0.80" # tissues.c: labels 1 and 15 (5th colour)
    ci="1.0 0.96 0.88" # the intensity's colour of bright tissue (volume_render.c, base)
    "$FTM_PNG_CHECK" nearest "$dir/lab.png" $left 80 $c1 $c15 $ci ||
        fail "png check: label 1's half not in its tissue colour"
    "$FTM_PNG_CHECK" nearest "$dir/lab.png" $right 80 $c15 $c1 $ci ||
        fail "png check: label 15's half not in its tissue colour"
    "$FTM_PNG_CHECK" nearest "$dir/labcut.png" $((cx - 60)) $((cy - 40)) $((cx - 15)) $((cy + 40)) \
        80 $c1 $c15 $ci || fail "png check: label 1's half of the section not in its colour"
    "$FTM_PNG_CHECK" nearest "$dir/labcut.png" $((cx + 15)) $((cy - 40)) $((cx + 60)) $((cy + 40)) \
        80 $c15 $c1 $ci || fail "png check: label 15's half of the section not in its colour"
    for box in "$left" "$right"; do
        "$FTM_PNG_CHECK" nearest "$dir/nolab.png" $box 80 $ci $c1 $c15 ||
            fail "png check: without the label map, not the intensity's colours"
    done
    [ -n "${FTM_KEEP_SCREENSHOT:-}" ] && cp "$dir/lab.png" "$dir/nolab.png" "$(dirname "$FTM_KEEP_SCREENSHOT")/"
    echo "PASS volumelabels: $(cat "$dir/lab.out")"
    ;;
reset)
    # a trainee's mouse probe (driven by xdotool in the client's X display)
    # pressed into the tissue; the instructor resets the tissue: the client
    # moves its probe out (it used to stay inside, pressing nothing at 0 N,
    # issue 27), so that a few more wheel notches touch the tissue again;
    # then key u brings the probe back above the tissue.
    command -v xdotool >/dev/null 2>&1 || { echo "SKIP: xdotool not installed"; exit 77; }
    start_server
    printf 'reset 0.3\n' >"$dir/reset.bot"
    cat >"$dir/drive.sh" <<DRIVE
# (run inside the client's X display; logs in $dir)
fail() { echo "FAIL: \$*"; kill \$c 2>/dev/null; exit 1; }
until_log() { # file, text, tries of 0.05 s
    i=0
    until grep -q -- "\$2" "\$1" 2>/dev/null; do
        i=\$((i + 1)); [ \$i -gt \$3 ] && return 1; sleep 0.05
    done
}
contacts() { grep -c "participant 11 probe 0: contact on triangle" "$dir/server.log"; }
"$FTM_CLIENT" $common --role trainee --id 11 --size 960x600 --log "$dir/trainee.log" \
    --duration 90 >"$dir/trainee.out" 2>"$dir/trainee.err" &
c=\$!
until_log "$dir/trainee.log" "participant id 11 is confirmed" 800 || fail "the trainee never joined"
until_log "$dir/trainee.log" "drawing" 400 || fail "the trainee drew no scene"
sleep 0.5
xdotool mousemove 480 300
# the wheel lowers the probe (1 mm a notch) until it touches
n=0
while [ "\$(contacts)" -lt 1 ]; do
    n=\$((n + 1)); [ \$n -gt 300 ] && fail "no contact after 300 wheel notches"
    xdotool click 5; sleep 0.03
done
echo "contact after \$n notches"
for i in 1 2 3 4 5 6 7 8; do xdotool click 5; sleep 0.05; done
sleep 0.3
# orbit (right drag) while in contact, then the wheel back out: the probe
# goes back along the normal where the contact began, so the contact
# releases in about as many notches as went in (9), the reaction staying
# along the normal (along the view ray it dragged the tissue sideways:
# 103 deg from the normal, issue 27)
xdotool mousemove 480 300 mousedown 3
for i in 1 2 3 4 5 6 7 8 9 10; do xdotool mousemove_relative -- 20 8; sleep 0.03; done
xdotool mouseup 3
sleep 0.3
n=0
until grep -q "probe: contact released" "$dir/trainee.log"; do
    n=\$((n + 1)); [ \$n -gt 40 ] && fail "no release after 40 notches out"
    xdotool click 4; sleep 0.08
done
echo "released after \$n notches out"
[ \$n -le 12 ] || fail "released after \$n notches out for 9 in"
ang=\$(sed -n 's/.*contact released .* at most \([0-9]*\) deg from the surface normal.*/\1/p' "$dir/trainee.log")
[ -n "\$ang" ] && [ "\$ang" -le 20 ] || fail "the reaction turned \$ang deg from the normal"
# back into the tissue for the reset below
n=0
while [ "\$(contacts)" -lt 2 ]; do
    n=\$((n + 1)); [ \$n -gt 40 ] && fail "no contact again after 40 notches"
    xdotool click 5; sleep 0.03
done
for i in 1 2 3 4 5; do xdotool click 5; sleep 0.05; done
sleep 0.5
timeout 60 "$FTM_BOT" --role instructor --id 12 $common --script "$dir/reset.bot" --duration 3 \
    >"$dir/bot.out" 2>"$dir/bot.err" || fail "the instructor bot exited with \$?"
until_log "$dir/server.log" "reset at tick" 100 || fail "the server did not reset"
until_log "$dir/trainee.log" "moved out to" 200 || fail "the probe was not moved out after the reset"
# out, so pushing again touches the tissue again (left inside, it would not)
n=0
while [ "\$(contacts)" -lt 3 ]; do
    n=\$((n + 1)); [ \$n -gt 40 ] && fail "no contact again after 40 notches past the reset"
    xdotool click 5; sleep 0.05
done
echo "contact again after \$n notches"
xdotool key u
until_log "$dir/trainee.log" "back above the tissue" 100 || fail "key u did not lift the probe"
# an instructor's key from a trainee: a word on screen (the HUD's notice), not only the log
xdotool key space
until_log "$dir/trainee.log" "pause: an instructor's key" 100 || fail "no word for an instructor's key"
kill \$c; wait \$c
# the help overlay: F1 shows it in the middle of the window
"$FTM_CLIENT" $common --role observer --size 960x600 --log "$dir/help.log" \
    --screenshot "$dir/help.png" --screenshot-after 2.5 >"$dir/help.out" 2>"$dir/help.err" &
c=\$!
until_log "$dir/help.log" "joining session" 200 || fail "the help client did not start"
sleep 0.3
xdotool key F1
wait \$c
"$FTM_PNG_CHECK" panel "$dir/help.png" 480 300 100 || fail "no help overlay after F1"
exit 0
DRIVE
    : >"$dir/x.xauth"
    ASAN_OPTIONS=$client_asan timeout 110 xvfb-run -a -f "$dir/x.xauth" -s "-screen 0 1280x800x24" \
        sh "$dir/drive.sh" >"$dir/drive.out" 2>&1 || fail "$(tail -n 3 "$dir/drive.out")"
    t_reset=$(sed -n 's/^\[ *\([0-9.]*\)\] info: reset at tick.*/\1/p' "$dir/server.log")
    t_again=$(sed -n 's/^\[ *\([0-9.]*\)\] info: participant 11 probe 0: contact on triangle.*/\1/p' \
        "$dir/server.log" | tail -n 1)
    awk -v r="$t_reset" -v a="$t_again" 'BEGIN { exit !(a > r) }' ||
        fail "the second contact ($t_again s) is not after the reset ($t_reset s)"
    echo "PASS reset: $(tr '\n' ' ' <"$dir/drive.out")$(grep -o 'moved out to .*' "$dir/trainee.log")"
    ;;
fps)
    # --max-fps holds under Xvfb, where the swap interval does not throttle:
    # the count of frames drawn over 3 s (the client's closing log line), with
    # wide margins (a behaviour check, not a speed test): --max-fps 20 between
    # 10 and 24 fps; the default (60) at most 72. An uncapped client under
    # Xvfb draws hundreds (740 fps at 640x400 on the 2-core machine).
    start_server
    client capped --max-fps 20 --duration 3 || fail "client (--max-fps 20) exited with $?"
    client default --duration 3 || fail "client (default cap) exited with $?"
    for run in capped default; do
        line=$(grep "drew [0-9]* frames in" "$dir/$run.log") || fail "$run: no frame count logged"
        eval "fps_$run=$(echo "$line" | sed -n 's/.*frames in [0-9.]* s (\([0-9.]*\) fps.*/\1/p')"
    done
    grep -q "fps; --max-fps 20)" "$dir/capped.log" || fail "the capped client did not say its cap"
    grep -q "fps; --max-fps 60)" "$dir/default.log" || fail "the default is not a cap of 60"
    grep -q "synced at tick" "$dir/capped.log" || fail "the capped client never synced"
    awk -v f="$fps_capped" 'BEGIN { exit !(f >= 10 && f <= 24) }' ||
        fail "--max-fps 20 drew $fps_capped fps, want 10..24"
    awk -v f="$fps_default" 'BEGIN { exit !(f > 0 && f <= 72) }' ||
        fail "the default cap drew $fps_default fps, want at most 72"
    echo "PASS fps: --max-fps 20: $fps_capped fps; default: $fps_default fps"
    ;;
*)
    echo "unknown mode $mode"; exit 2 ;;
esac
