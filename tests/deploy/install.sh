#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The installed tree, end to end (docs/deploy.md): `cmake --install` of this
# build into a scratch prefix, then, from a directory that is neither the
# source nor the build tree:
#   - the files a deployment needs are there;
#   - the systemd unit names this install's programs and data, systemd-analyze
#     accepts it (where installed), and its ExecStartPre command line (with
#     the loopback DDS configuration) passes `ftm-server --check`;
#   - a scene named by file name only is found in the installed
#     share/ftm/scenes by the server, by a trainee bot that learns the name
#     from the server's announcement, and by --replay; the bot ends on the
#     server's tick and hash; an unknown scene fails with the places tried;
#   - --record-dir makes a new recording per run, never overwriting, with
#     its session report beside it, equal to the report of its --replay;
#   - (unsanitized builds) a program compiled against the installed libftm
#     with pkg-config builds and runs a scene.
# Every process runs under `timeout`; the test has a CTest TIMEOUT.
set -u
: "${FTM_BUILD:?}" "${FTM_TEST_RATE:?}"
. "$(cd "$(dirname "$0")" && pwd)/../wait_for.sh"
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-install.XXXXXX")
trap 'rm -rf "$dir"' EXIT
p=$dir/prefix
fail() {
    echo "FAIL: $*"
    for f in "$dir"/*.out "$dir"/*.err "$dir"/*.log; do [ -f "$f" ] && { echo "== $f"; tail -n 20 "$f"; }; done
    exit 1
}
timeout 120 cmake --install "$FTM_BUILD" --prefix "$p" >"$dir/install.out" 2>&1 ||
    fail "cmake --install failed"
for f in bin/ftm bin/ftm-server bin/ftm-bot bin/ftm-plot-forces include/ftm/ftm.h include/ftm/sim.h lib/libftm.a \
         lib/pkgconfig/ftm.pc share/ftm/scenes/default.scene share/ftm/scenes/membrane.scene \
         share/ftm/cyclonedds/cyclonedds-lan.xml share/ftm/cyclonedds/cyclonedds-loopback.xml \
         share/ftm/sessions/trainee1.bot share/ftm/ftm-server.conf.example \
         lib/systemd/system/ftm-server@.service; do
    [ -e "$p/$f" ] || fail "not installed: $f"
done
mkdir -p "$dir/elsewhere" "$dir/state"
cd "$dir/elsewhere" || fail "cd"
unset FTM_SCENE_PATH CYCLONEDDS_URI
loop=$p/share/ftm/cyclonedds/cyclonedds-loopback.xml
# a DDS domain of its own among the server tests' (RUN_SERIAL, see tests/net)
domain=$(( 228 + $$ % 4 ))
session="install-$$"

# 1. the unit
unit=$p/lib/systemd/system/ftm-server@.service
grep -q "^ExecStart=$p/bin/ftm-server " "$unit" || fail "the unit's ExecStart is not this install's"
grep -q "^Environment=FTM_DDS_CONFIG=$p/share/ftm/cyclonedds/cyclonedds-lan.xml\$" "$unit" ||
    fail "the unit's DDS configuration is not this install's"
# the unit's documentation, and the README's links to docs/, resolve in the install
doc=$(sed -n 's|^Documentation=file://||p' "$unit")
[ -f "$doc" ] || fail "the unit's Documentation= names $doc, not installed"
for l in $(grep -o '](docs/[^)#]*' "$p/share/doc/ftm/README.md" | sed 's/^](//' | sort -u); do
    [ -e "$p/share/doc/ftm/$l" ] || fail "the installed README links to $l, not installed"
done
if command -v systemd-analyze >/dev/null 2>&1; then
    cp "$unit" "$dir/ftm-server@ci.service"
    timeout 60 systemd-analyze verify "$dir/ftm-server@ci.service" >"$dir/verify.out" 2>&1 ||
        fail "systemd-analyze verify rejects the unit"
    [ -s "$dir/verify.out" ] && fail "systemd-analyze verify warns about the unit"
    verified="systemd-analyze verify: clean"
else
    verified="systemd-analyze not installed: unit syntax not verified"
fi
# the ExecStartPre line as systemd would run it for session $session, with
# the default FTM_OPTIONS and the loopback configuration instead of the LAN's
opts=$(sed -n 's/^Environment="FTM_OPTIONS=\(.*\)"$/\1/p' "$unit")
[ -n "$opts" ] || fail "no default FTM_OPTIONS in the unit"
pre=$(sed -n 's/^ExecStartPre=//p' "$unit")
[ -n "$pre" ] || fail "no ExecStartPre in the unit"
cmd=$(printf '%s\n' "$pre" | sed -e "s|\\\$FTM_OPTIONS|$opts|" -e "s|\\\${FTM_SCENE}|default|" \
    -e "s|\\\${FTM_DDS_CONFIG}|$loop|" -e "s|%S|$dir/state|g" -e "s|%i|$session|g")
mkdir -p "$dir/state/ftm/$session" # StateDirectory=
# shellcheck disable=SC2086 # split as systemd splits $FTM_OPTIONS
timeout 60 $cmd --domain $domain --rt-priority 0 >"$dir/check.out" 2>"$dir/check.err" ||
    fail "the unit's ExecStartPre fails: $cmd"
grep -q "^ftm-server --check: ok" "$dir/check.out" || fail "--check did not say ok"

# 2. a scene by file name: found in the installed share/ftm/scenes
timeout 60 "$p/bin/ftm-server" --check --scene default.scene --config "$loop" --domain $domain \
    --session "$session" --rt-priority 0 >"$dir/check2.out" 2>"$dir/check2.err" ||
    fail "--check --scene default.scene failed"
grep -q "^scene  *default.scene ($p/bin/../share/ftm/scenes/default.scene): 1728 nodes" \
    "$dir/check2.out" || fail "default.scene not found in the installed scenes"
if timeout 60 "$p/bin/ftm-server" --check --scene nosuch.scene --config "$loop" \
    --domain $domain --rt-priority 0 >"$dir/nosuch.out" 2>"$dir/nosuch.err"; then
    fail "an unknown scene passed --check"
fi
grep -q "scene 'nosuch.scene' not found: .*tried nosuch.scene, $p/bin/../share/ftm/scenes/nosuch.scene" \
    "$dir/nosuch.err" || fail "no clear error for an unknown scene"
# a --check that would not start: an unwritable recording directory
if timeout 60 "$p/bin/ftm-server" --check --config "$loop" --domain $domain --rt-priority 0 \
    --record-dir "$dir/none" >"$dir/norec.out" 2>"$dir/norec.err"; then
    fail "--check passed with a missing recording directory"
fi
grep -q "^recording   FAILS: cannot create files in $dir/none: No such file or directory" \
    "$dir/norec.out" || fail "no clear --check failure for a missing recording directory"

# 3. a session on the installed tree: server, trainee bot, recording
mkdir -p "$dir/rec"
common="--session $session --domain $domain --config $loop"
timeout 60 "$p/bin/ftm-server" --scene default.scene $common --rate "$FTM_TEST_RATE" \
    --duration 3.5 --rt-priority 0 --record-dir "$dir/rec" --log "$dir/server.log" \
    >"$dir/server.out" 2>"$dir/server.err" &
server=$!
wait_for "$dir/server.log" "session '$session'" "server did not start"
timeout 60 "$p/bin/ftm-bot" --role trainee --script "$p/share/ftm/sessions/trainee1.bot" $common \
    --id 11 --duration 20 >"$dir/bot.out" 2>"$dir/bot.err"
wait $server || fail "server exited with $?"
want=$(sed -n 's/^ftm-server: \(final tick .*\)$/\1/p' "$dir/server.out")
got=$(sed -n 's/^ftm-bot 11: \(final tick .*\) synced$/\1/p' "$dir/bot.out")
[ -n "$want" ] && [ "$got" = "$want" ] || fail "bot: '$got', server: '$want'"
grep -q "scene 'default.scene': $p/bin/../share/ftm/scenes/default.scene" "$dir/bot.err" ||
    fail "the bot did not say where it found the announced scene"
grep -q "participant 11 probe 0: contact" "$dir/server.log" || fail "the trainee never touched the tissue"
set -- "$dir/rec/$session"-*.rec
[ $# -eq 1 ] && [ -s "$1" ] || fail "expected one recording in $dir/rec, found: $*"
rec=$1
case ${rec##*/} in
"$session"-[0-9][0-9][0-9][0-9][0-9][0-9][0-9][0-9]T[0-9][0-9][0-9][0-9][0-9][0-9]Z.rec) ;;
*) fail "recording name ${rec##*/} is not SESSION-YYYYMMDDTHHMMSSZ.rec" ;;
esac
timeout 60 "$p/bin/ftm-server" --replay "$rec" --report "$dir/replay.json" >"$dir/replay.out" \
    2>"$dir/replay.err" || fail "--replay of the installed session's recording failed"
# the run's report beside its recording, as the replay of the recording reports it
[ -s "${rec%.rec}.json" ] || fail "no report beside the recording"
cmp -s "${rec%.rec}.json" "$dir/replay.json" || fail "the report beside the recording differs from its replay's"
grep -q "\"session\":\"$session\"" "$dir/replay.json" || fail "the replay's report does not name the session"
# a second run in the same second or later: a new file, the first untouched
sum=$(cksum <"$rec")
timeout 60 "$p/bin/ftm-server" --scene default.scene $common --duration 0.3 --rt-priority 0 \
    --record-dir "$dir/rec" >"$dir/server2.out" 2>"$dir/server2.err" || fail "second server run failed"
set -- "$dir/rec/$session"-*.rec
[ $# -eq 2 ] || fail "a second run did not make a second recording: $*"
set -- "$dir/rec/$session"-*.json
[ $# -eq 2 ] || fail "a second run did not make a second report: $*"
[ "$(cksum <"$rec")" = "$sum" ] || fail "the first recording was changed by the second run"

# 4. libftm for other programs, through pkg-config
if [ -n "${FTM_SANITIZE:-}" ]; then
    embed="libftm with pkg-config: skipped in a sanitizer build (libftm.a needs its runtime)"
else
    cat >"$dir/embed.c" <<'CEOF'
#include <ftm/ftm.h>
#include <inttypes.h>
#include <stdio.h>
#include <string.h>
int main(void)
{
    ftm_scene *scene;
    ftm_sim *sim;
    ftm_error err;
    if (ftm_scene_open("default", &scene, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    ftm_sim_def def = ftm_scene_sim_def(scene);
    if (ftm_sim_create(ftm_scene_mesh(scene), &def, &sim, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    int32_t n = ftm_mesh_node_count(ftm_scene_mesh(scene));
    static double rest[3 * 4096];
    if (n > 4096)
        return 1;
    memcpy(rest, ftm_sim_positions(sim), 3 * (size_t)n * sizeof *rest);
    printf("%d nodes, hash %016" PRIx64, (int)n, ftm_sim_hash(sim));
    int rc = ftm_sim_run(sim, 100);
    if (rc) {
        fprintf(stderr, "%s\n", ftm_strerror(rc));
        return 1;
    }
    /* nothing touches the tissue: 100 steps leave every node where it was */
    int same = memcmp(rest, ftm_sim_positions(sim), 3 * (size_t)n * sizeof *rest) == 0;
    printf(", %s after 100 steps\n", same ? "at rest" : "MOVED");
    ftm_sim_destroy(sim);
    ftm_scene_destroy(scene);
    return 0;
}
CEOF
    flags=$(PKG_CONFIG_PATH="$p/lib/pkgconfig" pkg-config --cflags --libs ftm) ||
        fail "pkg-config does not know the installed ftm"
    # shellcheck disable=SC2086
    timeout 60 ${CC:-cc} -std=c17 -Wall -Werror -o "$dir/embed" "$dir/embed.c" $flags \
        >"$dir/cc.out" 2>&1 || fail "a program against the installed libftm does not build"
    timeout 60 "$dir/embed" >"$dir/embed.out" 2>&1 || fail "the embedding program failed"
    # the same state as the installed ftm tool's
    rest=$(timeout 60 "$p/bin/ftm" sim default --steps 0 --quiet) || fail "ftm sim failed"
    grep -q "^1728 nodes, $rest, at rest after 100 steps$" "$dir/embed.out" ||
        fail "embedding: '$(cat "$dir/embed.out")', ftm sim: '$rest'"
    embed="libftm with pkg-config: $(cat "$dir/embed.out")"
fi
echo "PASS install: $verified; ExecStartPre --check ok; bot and server on $want with" \
    "default.scene from share/ftm/scenes; recording ${rec##*/} replays, its report beside it" \
    "equals the replay's; $embed"
