#!/bin/sh
# The head's volume as ftm-client draws it, deformed by a scripted press
# (docs/client.md, "Frame rate"), Xvfb and Mesa's llvmpipe, 1280x800:
#   docs/img/client-volume-full.png   a slice per plane at the window's
#                                     resolution (--volume-scale 16), the
#                                     reference
#   docs/img/client-volume-step1.png  the default: a slice per plane at 1.5
#                                     pixels per voxel, scaled up
#   docs/img/client-volume-scale1.png the same at 1 pixel per voxel
#   docs/img/client-volume-step5.png  a slice per 5 planes, each sampling
#                                     its planes (the default until issue 32)
# and each one's difference from the reference around the contact and over
# the head (client-png-check similar).
#   docs/bench/volume_shots.sh [BUILD_DIR]   (default build/release)
set -eu
cd "$(dirname "$0")/../.."
B=${1:-build/release}
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-volume-shots.XXXXXX")
server= bot=
trap 'kill $server $bot 2>/dev/null; rm -rf "$dir"' EXIT
export CYCLONEDDS_URI= LIBGL_ALWAYS_SOFTWARE=1
session=volume-shots-$$
common="--session $session --domain $(( 220 + $$ % 10 )) --config deploy/cyclonedds-loopback.xml"
"$B/server/ftm-server" --scene head $common --duration 120 --log "$dir/server.log" >/dev/null 2>&1 &
server=$!
until grep -q "session '$session'" "$dir/server.log" 2>/dev/null; do sleep 0.05; done
"$B/bot/ftm-bot" --role trainee --script tests/client_gl/head.bot $common --id 11 --duration 110 \
    >/dev/null 2>&1 &
bot=$!
# head.bot holds its probe still from 3.5 s, about 0.5 s into the contact:
# 2500 ticks (2.5 s at the server's 1000 Hz) of contact, the press settled
for shot in "full --volume-scale 16" "step1" "scale1 --volume-scale 1" "step5 --volume-step 5"; do
    name=${shot%% *} opts=${shot#"$name"}
    # shellcheck disable=SC2086 # options
    xvfb-run -a -s "-screen 0 1280x800x24" "$B/client/ftm-client" $common --size 1280x800 \
        $opts --screenshot "docs/img/client-volume-$name.png" --screenshot-contact 2500 \
        --screenshot-timeout 60 >"$dir/$name.out" 2>"$dir/$name.err"
done
set -- $(sed -n 's/^screenshot .* contact \([0-9]*\) \([0-9]*\)$/\1 \2/p' "$dir/full.out")
for name in step1 scale1 step5; do
    for where in "$1 $2 60" "640 480 300"; do
        # shellcheck disable=SC2086 # x y r
        printf '%-7s %s\n' "$name" "$("$B/tests/client_gl/client-png-check" similar \
            docs/img/client-volume-full.png "docs/img/client-volume-$name.png" $where 4 |
            grep 'mean difference')"
    done
done
