#!/bin/sh
# Frame rate of the head scene's volume (docs/client.md, "Frame rate"):
# ftm-client under Xvfb with Mesa's llvmpipe, a scripted trainee pressing
# the top of the head over loopback DDS, several client configurations run
# in turn, round after round, so that the machine's load spoils a round of
# each rather than one configuration.
#   docs/bench/volume_fps.sh [BUILD_DIR] [SECONDS] [ROUNDS] [WxH] [CONFIG ...]
# A CONFIG is a quoted string of ftm-client options, "bin=PATH OPTIONS" to
# run another ftm-client (an older build, for a before-and-after in the
# same minutes); default:
#   "" "--volume-step 1" "--volume-step 10" "--cut" "--no-volume"
# Prints each run's line, then per configuration the median over the rounds
# of the per-run median frame rate.
set -u
cd "$(dirname "$0")/../.."
B=${1:-build/release}; secs=${2:-10}; rounds=${3:-3}; size=${4:-1280x800}
[ $# -gt 4 ] && shift 4 || set -- "" "--volume-step 1" "--volume-step 10" "--cut" "--no-volume"
cfg=deploy/cyclonedds-loopback.xml
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-volume-fps.XXXXXX")
server= bot=
trap 'kill $server $bot 2>/dev/null; rm -rf "$dir"' EXIT
export CYCLONEDDS_URI= LIBGL_ALWAYS_SOFTWARE=1
session=volume-fps-$$
common="--session $session --domain $(( 210 + $$ % 10 )) --config $cfg"
total=$(( (secs + 10) * rounds * $# + 30 ))
"$B/server/ftm-server" --scene head $common --duration "$total" --log "$dir/server.log" \
    >/dev/null 2>&1 &
server=$!
until grep -q "session '$session'" "$dir/server.log" 2>/dev/null; do sleep 0.05; done
# head.bot holds its press until 120 s: held longer for a longer benchmark
# (only when later than its last point: the bot refuses a script whose
# times do not increase, and the trainee then never touches)
awk -v T="$total" 'NF && $1 !~ /^#/ { last = $0 } { print } END { split(last, f);
    if (T + 10 > f[1]) printf("%d %s %s %s\n", T + 10, f[2], f[3], f[4]) }' \
    tests/client_gl/head.bot >"$dir/head.bot"
"$B/bot/ftm-bot" --role trainee --script "$dir/head.bot" $common --id 11 \
    --duration "$total" >/dev/null 2>"$dir/bot.err" &
bot=$!
sleep 5
for r in $(seq 1 "$rounds"); do
    i=0
    for c in "$@"; do
        i=$((i + 1))
        client=$B/client/ftm-client opts=$c
        case $c in bin=*) client=${c%% *}; client=${client#bin=}; opts=${c#bin="$client"} ;; esac
        # shellcheck disable=SC2086 # a configuration is a list of options
        line=$(timeout $(( secs + 60 )) xvfb-run -a -s "-screen 0 ${size}x24" \
            "$client" $common --role observer --size "$size" --bench "$secs" \
            --json $opts 2>"$dir/client.err" | grep fps_median)
        fps=$(printf '%s\n' "$line" | sed -n 's/.*"fps_median": \([0-9.]*\).*/\1/p')
        ms=$(printf '%s\n' "$line" | sed -n 's/.*"frame_ms_median": \([0-9.]*\).*/\1/p')
        [ -n "$fps" ] || { fps=0; ms=0; tail -3 "$dir/client.err"; }
        printf 'round %d  %-28s %7s fps (median frame %s ms)  load %s\n' "$r" "[${c:-default}]" \
            "$fps" "$ms" "$(cut -d' ' -f1 /proc/loadavg)"
        echo "$i $fps" >>"$dir/results"
    done
done
grep -q "contact on" "$dir/server.log" || echo "warning: the trainee never touched"
i=0
for c in "$@"; do
    i=$((i + 1))
    med=$(awk -v i=$i '$1 == i { print $2 }' "$dir/results" | sort -n |
        awk '{ v[n++] = $1 } END { print n ? v[int((n - 1) / 2)] : 0 }')
    printf 'median over %d rounds  %-28s %s fps\n' "$rounds" "[${c:-default}]" "$med"
done
