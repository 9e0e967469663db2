#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-client refuses out-of-range options with a message naming them, and
# exits 2 before it opens a window or joins anything (no display needed:
# every run also names a Cyclone configuration that does not exist).
set -u
fail() { echo "FAIL: $*"; exit 1; }
nodds=/nonexistent/ftm-test-cyclonedds.xml
. "$(cd "$(dirname "$0")" && pwd)/../refused.sh"
refused() { # expected-text options...
    want=$1
    shift
    refused_by "$want" "$FTM_CLIENT" --config $nodds "$@"
}
# a display name reaches others' HUDs and terminals: 1..63 bytes, no control bytes
refused "--name has control character 0x1b at byte 1" --name "$(printf 'a\033[31mb')"
refused "--name must be 1..63 bytes (got 64)" --name "$(printf '%064d' 0)"
refused "--name must be 1..63 bytes (got 0)" --name ""
# integers: range-checked, never cast to 32 bits nor read unsigned from a sign
refused "--domain must be an integer in 0..4294967294 (got '-1')" --domain -1
refused "--domain must be an integer in 0..4294967294 (got '4294967295')" --domain 4294967295
refused "--id must be an integer in 0..4294967295 (got '-1')" --id -1
refused "--id must be an integer in 0..4294967295 (got '4294967297')" --id 4294967297
refused "--msaa must be an integer in 0..16 (got '17')" --msaa 17
refused "--msaa must be an integer in 0..16 (got '4x')" --msaa 4x
refused "--swap-interval must be an integer in -1..8 (got '4294967297')" --swap-interval 4294967297
refused "--max-fps must be an integer in 0..1000 (got '-1')" --max-fps -1
refused "--max-fps must be an integer in 0..1000 (got '1001')" --max-fps 1001
refused "--volume-step must be 1, 2, 5 or 10, a divisor of the 10 slices per lattice cell (got '3')" \
    --volume-step 3
refused "--volume-step must be 1, 2, 5 or 10, a divisor of the 10 slices per lattice cell (got '20')" \
    --volume-step 20
refused "--volume-scale must be a number in (0, 16] (got '0')" --volume-scale 0
refused "--volume-scale must be a number in (0, 16] (got '17')" --volume-scale 17
refused "--screenshot-contact must be an integer in 0..9223372036854775807 (got '-5')" \
    --screenshot-contact -5
refused "--screenshot-tick must be an integer in 0..9223372036854775807 (got ' 7')" \
    --screenshot-tick " 7"
# times that would wrap when cast to nanoseconds
for v in 1e300 1e10 inf nan -1; do
    for o in --duration --bench --screenshot-after; do
        refused "$o must be a number of seconds in [0, 1e+09] (got '$v')" $o "$v"
    done
done
for v in 0 1e10 inf; do
    for o in --server-timeout --screenshot-timeout; do
        refused "$o must be a number of seconds in (0, 1e+09] (got '$v')" $o "$v"
    done
done
refused "--colormap-full must be a number of millimetres >= 0 (got '-1')" --colormap-full -1
# the option table's parser (getopt_long): a value that is itself an
# option is missing, not taken; flags take no value; prefixes must be unique
refused "--scene needs a value (NAME|FILE), not the option --duration" --scene --duration 2
refused "--screenshot needs a value (FILE.png)" --screenshot
refused "--cut takes no value" --cut=yes
refused "option --screenshot-t is ambiguous: --screenshot-tick, --screenshot-timeout" \
    --screenshot-t 5
refused "unknown option --colourmap" --colourmap
refused "--role must be trainee, instructor or observer (got 'viewer')" --role viewer
# outputs: never a file the client reads (by device and inode: another name,
# a hard link), nor a path it cannot write; refused before anything is
# opened for writing, the input left as it was
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm-client-options.XXXXXX")
trap 'chmod u+w "$tmp/ro" 2>/dev/null; rm -rf "$tmp"' EXIT
printf 'pause 1\nresume 2\n' >"$tmp/lesson.cmds"
printf '0 0.03 0.03 0.12\n1 0.03 0.03 0.12\n' >"$tmp/t.bot"
printf '<CycloneDDS/>\n' >"$tmp/cfg.xml"
ln "$tmp/lesson.cmds" "$tmp/link.cmds"
sums() { cksum "$tmp/lesson.cmds" "$tmp/t.bot" "$tmp/cfg.xml"; }
before=$(sums)
refused "--log $tmp/lesson.cmds is the file --commands $tmp/lesson.cmds reads" \
    --role instructor --commands "$tmp/lesson.cmds" --log "$tmp/lesson.cmds"
refused "--log $tmp/link.cmds is the file --commands $tmp/lesson.cmds reads" \
    --role instructor --commands "$tmp/lesson.cmds" --log "$tmp/link.cmds"
refused "--log $tmp/t.bot is the file --device $tmp/t.bot reads" \
    --role trainee --device "script:$tmp/t.bot" --log "$tmp/t.bot"
refused "--screenshot $tmp/t.bot is the file --device $tmp/t.bot reads" \
    --role trainee --device "script:$tmp/t.bot" --screenshot "$tmp/t.bot"
refused "--screenshot $tmp/cfg.xml is the file --config $tmp/cfg.xml reads" \
    --config "$tmp/cfg.xml" --screenshot "$tmp/cfg.xml"
refused "--log $tmp/cfg.xml is the file --config $tmp/cfg.xml reads" \
    --config "$tmp/cfg.xml" --log "$tmp/cfg.xml"
[ "$(sums)" = "$before" ] || fail "an input file was changed"
# outputs that cannot be written: said at once, status 2 (not after the wait)
refused "--screenshot '$tmp': is a directory" --screenshot "$tmp"
refused "--screenshot '$tmp/missing/x.png': its directory $tmp/missing: No such file" \
    --screenshot "$tmp/missing/x.png"
refused "--screenshot '': an empty path" --screenshot ""
refused "--log '$tmp': is a directory" --log "$tmp"
# a screenshot is renamed over its path: never over a link or a device
ln -s "$tmp/target.png" "$tmp/link.png"
refused "--screenshot '$tmp/link.png': is not a regular file" --screenshot "$tmp/link.png"
[ -L "$tmp/link.png" ] || fail "the symbolic link was replaced"
refused "--screenshot '/dev/null': is not a regular file" --screenshot /dev/null
[ -c /dev/null ] || fail "/dev/null is no longer a device"
mkdir "$tmp/ro" && chmod a-w "$tmp/ro"
if [ ! -w "$tmp/ro" ]; then # (root writes anyway)
    refused "--screenshot '$tmp/ro/x.png': its directory $tmp/ro cannot be written" \
        --screenshot "$tmp/ro/x.png"
fi
[ -z "$(ls -A "$tmp/ro")" ] || fail "a file was left in $tmp/ro"
# --size: two whole numbers and an x, nothing more
refused "--size must be WxH, each 64..8192 (got '100x100junk')" --size 100x100junk
refused "--size must be WxH, each 64..8192 (got ' 100x 100')" --size " 100x 100"
refused "--size must be WxH, each 64..8192 (got '100')" --size=100
# a bad device script is a bad argument: status 2, before any window
printf '0 0.03 0.03\n' >"$tmp/bad.bot"
refused "--device script:$tmp/bad.bot: $tmp/bad.bot:1:" --role trainee --device "script:$tmp/bad.bot"
refused "--device script:$tmp: $tmp: is a directory" --role trainee --device "script:$tmp"
refused "--device script:$tmp/none.bot: " --role trainee --device "script:$tmp/none.bot"
# an expectation is checked by a trainee bot only: --commands refuses it
printf 'pause 1\nexpect 0 1 contact no\n' >"$tmp/expect.cmds"
refused "ftm-client: $tmp/expect.cmds:2: 'expect' is checked by a trainee ftm-bot only" \
    --role instructor --commands "$tmp/expect.cmds"
# trainee options for another role: refused, not ignored
refused "--device needs --role trainee" --role observer --device "script:$tmp/t.bot"
refused "--renderer needs --role trainee" --role instructor --renderer extrapolate
exit 0
