#!/bin/sh
# The head's volume as ftm-client draws it by default (a slice per 5
# planes, each sampling its planes) and with a slice per plane
# (--volume-step 1, the paper's drawing), deformed by a scripted press:
# docs/img/client-volume-step5.png and client-volume-step1.png
# (docs/client.md, "Frame rate"). Xvfb and Mesa's llvmpipe, 1280x800.
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
for step in 5 1; do
    xvfb-run -a -s "-screen 0 1280x800x24" "$B/client/ftm-client" $common --size 1280x800 \
        --volume-step $step --screenshot "docs/img/client-volume-step$step.png" \
        --screenshot-contact 200 --screenshot-timeout 60
done
