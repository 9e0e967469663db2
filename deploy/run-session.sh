#!/usr/bin/env bash
# A headless training session on this machine, over loopback DDS:
# ftm-server with the default scene at 1 kHz, two scripted trainees pressing
# the tissue (docs/sessions/trainee*.bot) and an observer, for a few seconds.
# Prints what each process ended on and exits non-zero unless every
# participant replayed the session to the server's exact state.
#   deploy/run-session.sh [BUILD_DIR] [SECONDS]
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
seconds=${2:-6}
server="$build/server/ftm-server"
bot="$build/client/ftm-bot"
for p in "$server" "$bot"; do
  [ -x "$p" ] || { echo "run-session: $p not built" >&2; exit 2; }
done
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-session.XXXXXX")
trap '[ -n "${KEEP:-}" ] || rm -rf "$dir"' EXIT
common=(--session main-$$ --domain $((1 + $$ % 97)) --config deploy/cyclonedds-loopback.xml)

echo "FTM headless session on loopback: ftm-server (scene 'default', 1000 Hz, ${seconds} s)"
echo "  + trainee 11 (docs/sessions/trainee1.bot), trainee 12 (trainee2.bot), observer 13"
timeout $((seconds + 20)) "$server" --scene default "${common[@]}" --duration "$seconds" \
  --log "$dir/server.log" >"$dir/server.out" 2>&1 &
spid=$!
for _ in $(seq 100); do
  grep -q "session '" "$dir/server.log" 2>/dev/null && break
  sleep 0.05
done
timeout $((seconds + 20)) "$bot" --role trainee --script docs/sessions/trainee1.bot "${common[@]}" \
  --id 11 --duration $((seconds + 10)) --log "$dir/trainee11.csv" >"$dir/b11.out" 2>"$dir/b11.err" &
p11=$!
timeout $((seconds + 20)) "$bot" --role trainee --script docs/sessions/trainee2.bot "${common[@]}" \
  --id 12 --duration $((seconds + 10)) >"$dir/b12.out" 2>"$dir/b12.err" &
p12=$!
timeout $((seconds + 20)) "$bot" --role observer "${common[@]}" \
  --id 13 --duration $((seconds + 10)) >"$dir/b13.out" 2>"$dir/b13.err" &
p13=$!

status=0
wait $spid || { echo "server failed:"; tail -5 "$dir/server.out"; status=1; }
for p in $p11 $p12 $p13; do wait "$p" || status=1; done

echo
grep -E "contact on triangle|ticks in" "$dir/server.log" | sed 's/^/  server /'
want=$(sed -n 's/^ftm-server: final tick \(.*\)$/\1/p' "$dir/server.out")
echo "  server         final tick $want"
for b in 11 12 13; do
  got=$(sed -n "s/^ftm-bot $b: final tick \\(.*\\) synced\$/\\1/p" "$dir/b$b.out")
  stats=$(grep -o '[0-9]* mismatches.*' "$dir/b$b.err" | tail -1)
  mark="same state as the server"
  [ -n "$want" ] && [ "$got" = "$want" ] || { mark="DIFFERS from the server"; status=1; }
  echo "  participant $b final tick ${got:-?}: $mark ($stats)"
done
peak=$(awk -F, 'NR > 1 { f = sqrt($7*$7 + $8*$8 + $9*$9); if (f > m) m = f } END { printf "%.3g", m }' \
  "$dir/trainee11.csv")
echo "  trainee 11 peak reaction force: $peak N"
echo
if [ $status -eq 0 ]; then
  echo "result: every participant replayed the session bit-identically"
else
  echo "result: FAILED (logs kept in the messages above)"
fi
exit $status
