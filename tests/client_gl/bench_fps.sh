#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Frame rate of ftm-client under Xvfb + Mesa llvmpipe on the organ-like
# scene (client-organ: 20480 triangles), while a scripted trainee presses
# into it over loopback DDS (docs/client.md, "Frame rate").
#   tests/client_gl/bench_fps.sh BUILD_DIR [SECONDS] [RUNS] [WxH]
# Prints each run's result line and JSON, then the median over the runs.
set -u
B=${1:?build dir}; secs=${2:-15}; runs=${3:-3}; size=${4:-1280x800}
src=$(cd "$(dirname "$0")/../.." && pwd)
cfg=$src/deploy/cyclonedds-loopback.xml
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-bench-fps.XXXXXX")
trap 'kill $server $bot 2>/dev/null; rm -rf "$dir"' EXIT
export CYCLONEDDS_URI= LIBGL_ALWAYS_SOFTWARE=1
common="--session bench-fps-$$ --domain $(( 230 - $$ % 5 )) --config $cfg"
"$B/tests/client_gl/client-organ" "$dir" || exit 1
"$B/server/ftm-server" --scene "$dir/organ.scene" $common --duration $(( (secs + 8) * runs + 20 )) \
    --log "$dir/server.log" >/dev/null 2>&1 &
server=$!
sleep 1
"$B/bot/ftm-bot" --role trainee --script "$dir/press.bot" $common --id 11 \
    --duration $(( (secs + 8) * runs + 15 )) >/dev/null 2>"$dir/bot.err" &
bot=$!
sleep 2
for r in $(seq 1 "$runs"); do
    timeout $(( secs + 60 )) xvfb-run -a -s "-screen 0 ${size}x24" "$B/client/ftm-client" $common \
        --size "$size" --bench "$secs" --json 2>"$dir/client$r.err" | tee -a "$dir/results"
done
grep -c "contact on triangle" "$dir/server.log" >/dev/null || echo "warning: the trainee never touched"
awk -F'"fps_median": ' '/fps_median/ { split($2, a, ","); v[n++] = a[1] }
    END { if (!n) exit 1; for (i = 0; i < n; i++) for (j = i + 1; j < n; j++) if (v[j] < v[i]) { t = v[i]; v[i] = v[j]; v[j] = t }
          printf("median over %d runs of the per-run median frame rate: %.1f fps\n", n, v[int((n - 1) / 2)]) }' "$dir/results"
