#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-bot refuses out-of-range options with a message naming them, before
# it joins anything: every run names a Cyclone configuration that does not
# exist, so that a build without a check stops before DDS instead.
set -u
fail() { echo "FAIL: $*"; exit 1; }
nodds=/nonexistent/ftm-test-cyclonedds.xml
. "$(cd "$(dirname "$0")" && pwd)/../refused.sh"
refused() { # expected-text options...
    want=$1
    shift
    refused_by "$want" "$FTM_BOT" --role observer --config $nodds "$@"
}
# a display name reaches others' HUDs and terminals: 1..63 bytes, no control bytes
refused "--name has control character 0x1b at byte 1" --name "$(printf 'a\033[31mb')"
refused "--name must be 1..63 bytes (got 64)" --name "$(printf '%064d' 0)"
refused "--name must be 1..63 bytes (got 0)" --name ""
# times that would wrap when cast to nanoseconds (1e300: stop at once)
for v in 1e300 1e10 inf nan 0 -1; do
    refused "--duration must be a number of seconds in (0, 1e+09] (got '$v')" --duration $v
    refused "--resync-timeout must be a number of seconds in (0, 1e+09] (got '$v')" \
        --resync-timeout $v
done
# a period that floods the publishing queue
for v in 1e-12 0.00009 0 inf; do
    refused "--input-period must be a number of seconds in [0.0001, 1e+09] (got '$v')" \
        --input-period $v
done
# the option table's parser (getopt_long): a value that is itself an
# option is missing, not taken; the name of what is wrong is said
refused "--scene needs a value (NAME|FILE), not the option --duration" --scene --duration 2
refused "--log needs a value (FILE)" --log
refused "unknown option --nosuch" --nosuch 1
refused "option --re is ambiguous: --resync-timeout, --rejoin" --re 1
refused "unexpected argument 'stray'" stray
refused_by "--role is required" "$FTM_BOT" --config $nodds
refused_by "--role must be trainee, observer or instructor (got 'bot')" "$FTM_BOT" --role bot
# integers: range-checked, never cast to 32 bits nor read unsigned from a sign
refused "--id must be an integer in 0..4294967295 (got '-1')" --id -1
refused "--id must be an integer in 0..4294967295 (got '4294967297')" --id 4294967297
refused "--domain must be an integer in 0..4294967294 (got '-1')" --domain -1
refused "--domain must be an integer in 0..4294967294 (got '4294967296')" --domain 4294967296
refused "--domain must be an integer in 0..4294967294 (got '1x')" --domain 1x
# expectations: only a trainee has a probe to check; a bad one is a script
# error naming its line, before DDS
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm-bot-options.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
printf 'pause 1\nexpect 0 1 contact no\n' >"$tmp/instructor.bot"
refused "ftm-bot: $tmp/instructor.bot:2: 'expect' needs --role trainee" --script "$tmp/instructor.bot"
refused_by "ftm-bot: $tmp/instructor.bot:2: 'expect' needs --role trainee" \
    "$FTM_BOT" --role instructor --config $nodds --script "$tmp/instructor.bot"
printf '0 0.03 0.03 0.12\nexpect 2 1 force 0 1\n' >"$tmp/reversed.bot"
refused_by "$tmp/reversed.bot:2: the window ends before it starts (2 > 1)" \
    "$FTM_BOT" --role trainee --config $nodds --script "$tmp/reversed.bot"
printf '0 0.03 0.03 0.12\nexpect 0 1 contact no\n' >"$tmp/good.bot"
out=$(timeout 20 "$FTM_BOT" --role trainee --config $nodds --script "$tmp/good.bot" 2>&1)
case $out in *"Cyclone DDS configuration $nodds"*) ;; *) fail "a good expectation refused: $out" ;; esac
# the limits themselves pass the options and fail only at the configuration;
# so do --opt=value and an unambiguous prefix (--dur, --inp)
out=$(timeout 20 "$FTM_BOT" --role=observer --config=$nodds --dur 1e9 --resync-timeout=1e9 \
    --inp 0.0001 --id 4294967295 --domain=4294967294 2>&1)
case $out in *"Cyclone DDS configuration $nodds"*) ;; *) fail "the limits refused: $out" ;; esac
# --help: the options from the table, on stdout, status 0
out=$(timeout 20 "$FTM_BOT" --help) || fail "--help: exit status $?"
case $out in *"--input-period S"*"-h, --help"*) ;; *) fail "--help lacks the options: $out" ;; esac
echo "PASS bot options"
