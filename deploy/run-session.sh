#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# A headless training session on this machine, over loopback DDS:
# ftm-server with the palpation scene (neo-Hookean tissue, elastic far
# field: docs/feel.md; FTM_SCENE=NAME runs another) at 1 kHz, two scripted trainees pressing
# the tissue (docs/sessions/trainee*.bot), an instructor who makes the tissue
# stiffer 1.5 s in (docs/sessions/instructor.bot) and an observer, for a few
# seconds.
# Prints what each process ended on and exits non-zero unless every
# participant replayed the session to the server's exact state and the
# trainees felt what their scripts expect (docs/bot-script.md, Expectations;
# their presses end 2.4 s in, so a session lasts at least 3 s).
# With a display (DISPLAY or WAYLAND_DISPLAY set, ftm-client built, and
# FTM_HEADLESS unset, empty or 0) an instructor window (ftm-client) joins too, the
# trainees repeat their presses every 3 s, and the session lasts 60 s by
# default: watch, rotate (drag), toggle the colour map (c) and the BFS region
# (b), pause (Space); docs/client.md lists the keys.
# A window that cannot open (a stale DISPLAY) is reported and the session
# goes on without it. Ctrl-C (or SIGTERM, SIGHUP) stops every process of
# the session. KEEP=1 keeps the logs; a failed or interrupted session
# keeps them anyway.
#   deploy/run-session.sh [BUILD_DIR] [SECONDS]
set -uo pipefail
usage() { sed -n 's/^#   \(deploy\/run-session.sh .*\)$/usage: \1/p' "$0"; }
case ${1:-} in -h|--help) usage; exit 0 ;; esac
cd "$(dirname "$0")/.."
build=${1:-build/release}
server="$build/server/ftm-server"
bot="$build/bot/ftm-bot"
client="$build/client/ftm-client"
gui=
case ${FTM_HEADLESS:-0} in 0|'') headless= ;; *) headless=1 ;; esac
if [ -z "$headless" ] && { [ -n "${DISPLAY:-}" ] || [ -n "${WAYLAND_DISPLAY:-}" ]; } &&
   [ -x "$client" ]; then
  gui=1
fi
seconds=${2:-$([ -n "$gui" ] && echo 60 || echo 6)}
if ! [[ $seconds =~ ^[1-9][0-9]{0,4}$ ]] || [ "$seconds" -lt 3 ] || [ "$seconds" -gt 86400 ]; then
  echo "run-session: SECONDS must be a whole number of seconds, 3..86400: the trainees' presses take 2.4 s (got '$seconds')" >&2
  usage >&2
  exit 2
fi
for p in "$server" "$bot"; do
  [ -x "$p" ] || { echo "run-session: $p not built" >&2; exit 2; }
done
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-session.XXXXXX") && [ -d "$dir" ] || {
  echo "run-session: cannot create a directory for the session's logs under ${TMPDIR:-/tmp}" >&2
  exit 2
}
trap 'case ${KEEP:-0} in 0|"") rm -rf "$dir" ;; esac' EXIT
# the session's processes run under `timeout`, which puts itself in a
# process group of its own, so a Ctrl-C in the terminal reaches only this
# script: stop them all (timeout passes the signal on), then leave
stop() {
  trap - INT TERM HUP
  KEEP=1
  echo "run-session: interrupted: stopping the session's processes (logs kept in $dir)" >&2
  # every background job of this script, one started the moment before
  # the signal included
  running=$(jobs -p)
  [ -z "$running" ] || kill -TERM $running 2>/dev/null
  wait
  exit "$1"
}
trap 'stop 130' INT
trap 'stop 143' TERM
trap 'stop 129' HUP
# the accurate model by default; the scripts are written for the 12x12x12
# lattice that palpation and default share
scene=${FTM_SCENE:-palpation}
common=(--session main-$$ --domain $((1 + $$ % 97)) --config deploy/cyclonedds-loopback.xml)

# a scene with scripts of its own (docs/sessions/NAME/ for the scene file
# NAME.scene, e.g. FTM_SCENE=docs/scenes/brain.scene) runs those
scripts=docs/sessions
base=$(basename "$scene" .scene)
[ "$base" != "$scene" ] && [ -d "docs/sessions/$base" ] && scripts=docs/sessions/$base
script1=$scripts/trainee1.bot
script2=$scripts/trainee2.bot
script15=$scripts/instructor.bot
[ -r "$script15" ] || script15=docs/sessions/instructor.bot
if [ -n "$gui" ]; then
  # the scripted presses again every 3 s, for as long as the window is watched
  loop() { awk -v reps=$((seconds / 3 + 1)) '!/^#/ && NF == 4 { t[n] = $1; l[n++] = $2 " " $3 " " $4 }
    END { for (k = 0; k < reps; k++) for (i = 0; i < n; i++) print t[i] + 3 * k, l[i] }' "$1" >"$2"; }
  loop "$script1" "$dir/t1.bot"; script1="$dir/t1.bot"
  loop "$script2" "$dir/t2.bot"; script2="$dir/t2.bot"
  echo "FTM session on loopback with an instructor window: ftm-server (scene '$scene', 1000 Hz, ${seconds} s)"
else
  echo "FTM headless session on loopback: ftm-server (scene '$scene', 1000 Hz, ${seconds} s)"
fi
echo "  + trainee 11 ($script1), trainee 12 (trainee2.bot), observer 13,"
echo "    instructor 15 ($script15: $(grep -v '^#' "$script15" | awk 'NF' | tr '\n' ';' | sed 's/;$//;s/;/; /g'))"
[ -n "$gui" ] && echo "  + instructor 14: ftm-client window (keys: docs/client.md)"
timeout $((seconds + 20)) "$server" --scene "$scene" "${common[@]}" --duration "$seconds" \
  --log "$dir/server.log" --report "$dir/report.json" --record "$dir/session.rec" \
  >"$dir/server.out" 2>&1 &
spid=$!
for _ in $(seq 100); do
  grep -q "session '" "$dir/server.log" 2>/dev/null && break
  sleep 0.05
done
timeout $((seconds + 20)) "$bot" --role trainee --script "$script1" "${common[@]}" \
  --id 11 --duration $((seconds + 10)) --log "$dir/trainee11.csv" >"$dir/b11.out" 2>"$dir/b11.err" &
p11=$!
timeout $((seconds + 20)) "$bot" --role trainee --script "$script2" "${common[@]}" \
  --id 12 --duration $((seconds + 10)) >"$dir/b12.out" 2>"$dir/b12.err" &
p12=$!
timeout $((seconds + 20)) "$bot" --role observer "${common[@]}" \
  --id 13 --duration $((seconds + 10)) >"$dir/b13.out" 2>"$dir/b13.err" &
p13=$!
timeout $((seconds + 20)) "$bot" --role instructor --script "$script15" \
  "${common[@]}" --id 15 --duration $((seconds + 10)) >"$dir/b15.out" 2>"$dir/b15.err" &
p15=$!
if [ -n "$gui" ]; then
  "$client" --role instructor "${common[@]}" --id 14 --name instructor --duration "$seconds" \
    --log "$dir/client.log" >"$dir/client.out" 2>&1 &
  p14=$!
fi

status=0
wait $spid || { echo "server failed:"; tail -5 "$dir/server.out"; status=1; }
for p in $p11 $p12 $p13 $p15; do wait "$p" || status=1; done

echo
grep -E "contact on triangle|tissue from tick|ticks in" "$dir/server.log" |
  sed -e 's/, node mass .*//' -e 's/^/  server /'
want=$(sed -n 's/^ftm-server: final tick \(.*\)$/\1/p' "$dir/server.out")
echo "  server         final tick $want"
for b in 11 12 13 15; do
  got=$(sed -n "s/^ftm-bot $b: final tick \\(.*\\) synced\$/\\1/p" "$dir/b$b.out")
  stats=$(grep -o '[0-9]* mismatches.*' "$dir/b$b.err" | tail -1)
  mark="same state as the server"
  [ -n "$want" ] && [ "$got" = "$want" ] || { mark="DIFFERS from the server"; status=1; }
  echo "  participant $b final tick ${got:-?}: $mark ($stats)"
done
# what the trainees' scripts expect them to feel (docs/bot-script.md,
# Expectations; a failure is also the bot's exit status 4)
expects=$(grep -h ": expect " "$dir/b11.err" "$dir/b12.err" 2>/dev/null)
if [ -n "$expects" ]; then
  echo "  trainees' expectations: $(grep -c ': ok (' <<<"$expects") of $(grep -c '' <<<"$expects") held"
  grep ': FAILED' <<<"$expects" | sed 's/^/    /'
fi
# what the server replied to the instructor's commands (a refused or
# unanswered one is also the bot's exit status 4)
cmds=$(sed -n 's/^ftm-bot 15 \[ *[0-9.]*\] commands: //p' "$dir/b15.err" | tail -1)
[ -z "$cmds" ] || echo "  instructor's commands: $cmds"
grep -E "command .*: (refused|no reply)" "$dir/b15.err" | sed 's/^ftm-bot 15 \[ *[0-9.]*\] /    /'
peak=$(awk -F, 'NR > 1 { f = sqrt($7*$7 + $8*$8 + $9*$9); if (f > m) m = f } END { printf "%.3g", m }' \
  "$dir/trainee11.csv")
echo "  trainee 11 peak reaction force: $peak N (as its bot received it)"
echo "  debriefing, from the server's session report (--report; KEEP=1 keeps $dir/report.json):"
sed -n 's/^\[ *[0-9.]*\] info: \(participant .* probe [0-9]*: [0-9]* touch.*\)$/    \1/p' "$dir/server.log"
# the recording, replayed: the same ticks and hashes again, and the force
# each trainee felt over time (--reactions) as a picture
if "$server" --replay "$dir/session.rec" --reactions "$dir/forces.csv" >"$dir/replay.out" \
     2>"$dir/replay.err"; then
  echo "  recording replayed: $(sed -n 's/^replay [^:]*: \(.*every hash equal\).*/\1/p' "$dir/replay.out")"
  if command -v gnuplot >/dev/null 2>&1 &&
     deploy/ftm-plot-forces "$dir/forces.csv" "$dir/forces.png" "$dir/report.json" >/dev/null; then
    echo "  force over time: $dir/forces.png (deploy/ftm-plot-forces; KEEP=1 keeps it)"
  fi
else
  echo "  the recording did not replay:"; tail -3 "$dir/replay.err" | sed 's/^/    /'; status=1
fi
if [ -n "$gui" ]; then
  wait $p14; rc=$?
  if [ $rc -ne 0 ] && grep -q "cannot initialise GLFW\|cannot open an OpenGL" "$dir/client.out"; then
    # a display that does not work (a stale DISPLAY): the session ran without the window
    echo "  instructor window: could not open on '${DISPLAY:-${WAYLAND_DISPLAY:-}}', the session ran without it:"
    grep "cannot initialise GLFW\|cannot open an OpenGL" "$dir/client.out" | head -n 2 | sed 's/^/    /'
  else
    echo "  instructor window: exit $rc ($(grep -c "" "$dir/client.log" 2>/dev/null || echo 0) log lines)"
    [ $rc -eq 0 ] || { tail -5 "$dir/client.out"; status=1; }
  fi
fi
echo
if [ $status -eq 0 ]; then
  echo "result: every participant replayed the session bit-identically"
else
  KEEP=1
  echo "result: FAILED (the session's logs are kept in $dir)"
fi
exit $status
