#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-server refuses out-of-range options with a message naming them, and
# accepts the limits themselves (--offline: no DDS involved; where a build
# without the check would start a session, a configuration that does not
# exist stops it before DDS).
set -u
fail() { echo "FAIL: $*"; exit 1; }
dir=$(mktemp -d "${TMPDIR:-/tmp}/ftm-server-options.XXXXXX")
trap 'rm -rf "$dir"' EXIT
nodds=/nonexistent/ftm-test-cyclonedds.xml
refused() { # expected-text options...
    want=$1
    shift
    if out=$(timeout 20 "$FTM_SERVER" "$@" 2>&1); then fail "accepted: $*"; fi
    case $out in *"$want"*) ;; *) fail "$*: no '$want' in: $out" ;; esac
}
refused "--heartbeat must be a number of seconds in (0, 10] (got '10.5')" --heartbeat 10.5 --offline 1
refused "--heartbeat must be a number of seconds in (0, 10] (got '0')" --heartbeat 0 --offline 1
# whole hertz, as announced and recorded (0.1 Hz was announced as 0); the
# message names the rate alone (it used to blame a valid --heartbeat too)
for v in 100001 0 0.1 0.9 333.3; do
    refused "--rate must be a whole number of hertz in [1, 100000] (got '$v')" --rate "$v" --offline 1
    out=$(timeout 20 "$FTM_SERVER" --rate "$v" --offline 1 2>&1)
    case $out in *heartbeat*) fail "--rate $v: the message blames --heartbeat: $out" ;; esac
done
for v in 0 -0.01 nan inf 1e999 1e-999 5cm; do
    refused "--max-penetration must be a number of metres > 0 (got '$v')" --max-penetration "$v" --offline 1
done
refused "--replay, --inputs and --offline exclude each other" --replay a.rec --inputs b.rec
refused "--record goes with a session or --inputs" --offline 5 --record x.rec
refused "--record goes with a session or --inputs" --replay a.rec --record x.rec
refused "ftm-server --inputs: /nonexistent/a.rec" --inputs /nonexistent/a.rec
for v in localhost 127.0.0 300.1.1.1 ::g ''; do
    refused "--metrics-addr needs an IPv4 or IPv6 address (got '$v')" --metrics-addr "$v" --offline 1
done
refused "--record-dir goes with a session, without --record" --record-dir /tmp --record x.rec
refused "--record-dir goes with a session, without --record" --record-dir /tmp --offline 5
refused "--check checks a session's set-up: not with --replay" --check --replay a.rec
for v in x -1 1024 2x ''; do
    refused "--rt-cpu must be 'start', 'any' or a CPU number in 0..1023 (got '$v')" --rt-cpu "$v" --offline 1
done
refused "--check checks a session's set-up: not with --replay" --offline 5 --check
t="--trainee 1:0:a.bot"
# shellcheck disable=SC2086 # nine options
refused "--trainee given more than 8 times: at most 8 trainees" --offline 5 $t $t $t $t $t $t $t $t $t
# integers: range-checked, never cast to 32 bits (4294967376 is 80 mod 2^32,
# 4294967297 is 1, 4294967304 is 8) nor read unsigned from a sign
refused "--metrics-port must be an integer in 0..65535 (got '4294967376')" --metrics-port 4294967376 --offline 1
refused "--metrics-port must be an integer in 0..65535 (got '-1')" --metrics-port -1 --offline 1
refused "--adaptive must be an integer in 0..1 (got '4294967297')" --adaptive 4294967297 --offline 1
refused "--depth must be an integer in 0..1000000 (got '4294967304')" --depth 4294967304 --offline 1
refused "--depth must be an integer in 0..1000000 (got '-5')" --depth -5 --offline 1
refused "--depth-floor must be an integer in 0..1000000 (got '-2')" --depth-floor -2 --offline 1
refused "--id must be an integer in 1..4294967295 (got '-1')" --id -1 --offline 1
refused "--id must be an integer in 1..4294967295 (got '4294967296')" --id 4294967296 --offline 1
refused "--domain must be an integer in 0..4294967294 (got '-1')" --domain -1 --offline 1
refused "--rt-priority must be an integer in 0..98 (got '99')" --rt-priority 99 --offline 1
refused "--offline must be an integer in 1..9223372036854775807 (got '99999999999999999999')" \
    --offline 99999999999999999999
for v in 1x '' ' 5' 0x10 1e3; do
    refused "--depth must be an integer in 0..1000000 (got '$v')" --depth "$v" --offline 1
done
# --offline 0 is no tick count (it used to start a live session)
refused "--offline must be an integer in 1..9223372036854775807 (got '0')" --offline 0 --config $nodds
printf '0 0 0 0.2\n1 0 0 0.1\n' >"$dir/hip.bot"
refused "--trainee '4294967297:0:$dir/hip.bot': expected ID:T0:FILE, ID in 1..4294967295" \
    --id 2 --offline 5 --trainee "4294967297:0:$dir/hip.bot"
refused "--trainee '-11:0:$dir/hip.bot': expected ID:T0:FILE, ID in 1..4294967295" \
    --offline 5 --trainee "-11:0:$dir/hip.bot"
# a trainee script without HIP positions (it used to exit 2 saying nothing)
printf 'join 1.0\n' >"$dir/nohip.bot"
refused "--trainee '11:0:$dir/nohip.bot': $dir/nohip.bot has no HIP positions" \
    --offline 5 --trainee "11:0:$dir/nohip.bot"
# times that would wrap to 0 ns when cast: a keyframe every tick, a stop at once
for v in 1e11 inf nan 0; do
    refused "--keyframe-every must be a number of seconds in (0, 1e+09] (got '$v')" --keyframe-every $v --offline 1
done
for v in 1e17 1000000001 inf nan -1; do
    refused "--duration must be a number of seconds in [0, 1e+09] (got '$v')" --duration $v --offline 1
done
# the option table's parser (getopt_long): a value that is itself an
# option is missing, not taken (issue 28: it used to say "2 needs a value");
# prefixes must be unique; flags take no value; no stray words
refused "--scene needs a value (NAME|FILE), not the option --duration" --scene --duration 2
refused "--report needs a value (FILE)" --offline 1 --report
refused "option --depth- is ambiguous: --depth-floor, --depth-hold-up" --depth- 2 --offline 1
refused "--check takes no value" --check=1
refused "unknown option --ofline" --ofline 5
refused "unexpected argument 'default'" --scene default default --offline 1
refused "--depth-floor must be at most --depth" --depth 4 --depth-floor 5 --offline 1
# metrics on an address nothing can connect to
for v in 224.0.0.1 239.255.255.250 255.255.255.255 ff02::1 ::ffff:224.0.0.1; do
    refused "--metrics-addr $v is a multicast or broadcast address" --metrics-addr $v --offline 1
done
# an output that is a directory: refused at start, not after the run
refused "--report $dir is a directory" --offline 3 --report "$dir"
# a directory as the scene: said as such (it used to be "read error")
refused "$dir: is a directory, not a file" --offline 3 --scene "$dir"
# --upto-damage goes with what reads a recording
refused "--upto-damage goes with --replay or --inputs" --offline 3 --upto-damage
# --resume: a session of its own lesson; --resume-recent: with --record-dir
refused "--resume goes with a session, without --record or --record-dir" --resume a.rec --record b.rec
refused "--resume goes with a session, without --record or --record-dir" --resume a.rec --record-dir /tmp
refused "--resume goes with a session, without --record or --record-dir" --resume a.rec --replay b.rec
refused "--resume-recent goes with --record-dir" --resume-recent 60 --offline 3
refused "--resume-full goes with --resume or --resume-recent" --resume-full --offline 3
refused "ftm-server --resume: /nonexistent/a.rec: cannot open" --resume /nonexistent/a.rec
refused "--resume-recent must be a number of seconds" --resume-recent 0 --record-dir /tmp
refused "--reactions $dir is a directory" --offline 3 --reactions "$dir"
refused "--log $dir is a directory" --offline 3 --log "$dir"
[ -z "$(ls "$dir"/*.json 2>/dev/null)" ] || fail "a report was written"
timeout 20 "$FTM_SERVER" --heartbeat 10 --rate 100000 --offline 5 >/dev/null 2>&1 ||
    fail "--heartbeat 10 --rate 100000 refused"
# --opt=value and unambiguous prefixes (--heart, --off) are the options
timeout 20 "$FTM_SERVER" --heart=10 --rate=100000 --off 5 >/dev/null 2>&1 ||
    fail "--heart=10 --rate=100000 --off 5 refused"
out=$(timeout 20 "$FTM_SERVER" --help) || fail "--help: exit status $?"
case $out in *"--rt-cpu start|any|N"*"-h, --help"*) ;; *) fail "--help lacks the options: $out" ;; esac
timeout 20 "$FTM_SERVER" --keyframe-every 1e9 --duration 1e9 --depth 1000000 --depth-floor 0 \
    --metrics-port 65535 --id 4294967295 --domain 4294967294 --adaptive 1 --rt-priority 0 \
    --offline 1 >/dev/null 2>&1 || fail "the limits of the time and integer options refused"
timeout 20 "$FTM_SERVER" --offline 5 --id 2 --trainee "4294967295:0:$dir/hip.bot" \
    --report "$dir/r.json" >/dev/null 2>&1 || fail "trainee id 4294967295 refused"
grep -q '"id": *4294967295' "$dir/r.json" || fail "the report has no trainee 4294967295"
echo "PASS server options"
