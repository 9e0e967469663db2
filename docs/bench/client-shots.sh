#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Screenshots of ftm-client for docs/client.md and the README, taken the way
# the tests take them: a real ftm-server on loopback DDS, scripted trainees
# (ftm-bot), and ftm-client under Xvfb with Mesa's software renderer.
#   docs/bench/client-shots.sh [BUILD_DIR]      (default build/release)
# Writes docs/img/client-*.png. FTM_SHOTS_NO_VOLUME=1 leaves out the head's
# volume (parts 4 and 5); parts 6 to 9 need xdotool (keys in the window).
set -eu
cd "$(dirname "$0")/../.."
B=${1:-build/release}
cfg=deploy/cyclonedds-loopback.xml
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-shots.XXXXXX")
pids=
trap 'kill $pids 2>/dev/null; rm -rf "$dir"' EXIT
export LIBGL_ALWAYS_SOFTWARE=1 CYCLONEDDS_URI=

# one session: $1 = tag, $2 = scene; trainees from docs/sessions/ pressing
session_start() {
    session="shots-$1-$$"
    common="--session $session --domain $(( 200 + $$ % 10 )) --config $cfg"
    "$B/server/ftm-server" --scene "$2" $common --duration 60 --log "$dir/$1-server.log" \
        >/dev/null 2>&1 &
    pids="$pids $!"
    until grep -q "session '$session'" "$dir/$1-server.log" 2>/dev/null; do sleep 0.05; done
}
shot() { # file, then client options
    f=$1; shift
    timeout 90 xvfb-run -a -s "-screen 0 1280x800x24" "$B/client/ftm-client" $common \
        --size 1280x800 "$@" --screenshot "$f" --screenshot-timeout 60 >"$dir/shot.out" 2>&1 ||
        { cat "$dir/shot.out"; exit 1; }
    cat "$dir/shot.out"
}

# 1. the default scene, one trainee pressing 6 mm off-centre: the tissue as
#    drawn by default, its name label and the HUD, seen by an observer
session_start press default
"$B/bot/ftm-bot" --role trainee --script tests/client_gl/hold.bot $common --id 11 \
    --duration 50 >/dev/null 2>&1 &
pids="$pids $!"
shot docs/img/client-press.png --role observer --screenshot-contact 300
# 2. the same contact with the active BFS region drawn (key b)
shot docs/img/client-region.png --role observer --region --colormap --screenshot-contact 300
# 6. a trainee's own view: its mouse probe where it starts, the instrument,
#    the line and shadow to the surface below and its height on the HUD;
#    the bot's instrument pressing beside it
shot docs/img/client-probe.png --role trainee --id 21 --screenshot-after 3
# 7. the help overlay (F1), a trainee's
: >"$dir/x.xauth"
timeout 90 xvfb-run -a -f "$dir/x.xauth" -s "-screen 0 1280x800x24" sh -c "
    '$B/client/ftm-client' $common --size 1280x800 --role trainee --id 22 \
        --screenshot docs/img/client-help.png --screenshot-after 3 >'$dir/help.out' 2>&1 &
    sleep 1.5; xdotool key F1; wait"
kill $pids 2>/dev/null || true
pids=
sleep 1

# 3. two trainees on one tissue (their regions merge, paper 3.1.6), seen by the
#    instructor
session_start two default
# each waits above the tissue until the server knows it, then presses and holds
printf '0 0.035 0.035 0.12\n2.5 0.035 0.035 0.12\n3.5 0.035 0.035 0.105\n60 0.035 0.035 0.105\n' \
    >"$dir/t1.bot"
printf '0 0.065 0.055 0.12\n2.5 0.065 0.055 0.12\n3.5 0.065 0.055 0.107\n60 0.065 0.055 0.107\n' \
    >"$dir/t2.bot"
for i in 1 2; do
    "$B/bot/ftm-bot" --role trainee --script "$dir/t$i.bot" $common --id 1$i \
        --duration 50 >/dev/null 2>&1 &
    pids="$pids $!"
done
shot docs/img/client-instructor.png --role instructor --screenshot-contact 300
# 8. the instructor's HUD in a 640 px window (wrapped, nothing cut off)
shot docs/img/client-hud-640.png --role instructor --size 640x480 --screenshot-contact 300
# 9. a mistyped session name (another case): the waiting screen's picker
shot docs/img/client-picker.png --role trainee --id 23 --session "SHOTS-TWO-$$" \
    --size 960x600 --screenshot-after 5
kill $pids 2>/dev/null || true
pids=
sleep 1
[ -n "${FTM_SHOTS_NO_VOLUME:-}" ] && { echo "wrote docs/img/client-*.png (no volume)"; exit 0; }

# 4. the built-in head scene: a volume embedded in its control lattice (paper
#    4.2), drawn as deformed slices, a trainee pressing the top of the head
session_start volume head
"$B/bot/ftm-bot" --role trainee --script tests/client_gl/head.bot $common --id 11 \
    --duration 50 >/dev/null 2>&1 &
pids="$pids $!"
shot docs/img/client-volume.png --role observer --screenshot-contact 300
# 5. the same, cut away through the middle (key x): the section
shot docs/img/client-volume-cut.png --role observer --cut --screenshot-contact 300
echo "wrote docs/img/client-press.png docs/img/client-region.png docs/img/client-instructor.png" \
    "docs/img/client-volume.png docs/img/client-volume-cut.png"
