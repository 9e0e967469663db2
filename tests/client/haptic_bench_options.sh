#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# ftm-haptic-bench refuses what it cannot do, with a message naming it and
# status 2, before computing anything.
set -u
fail() { echo "FAIL: $*"; exit 1; }
. "$(cd "$(dirname "$0")" && pwd)/../refused.sh"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm-bench-options.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
# a path too long for its tick count (1e7 s was an out-of-range cast to int32)
printf '0 0.06 0.06 0.12\n1e7 0.06 0.06 0.12\n' >"$tmp/long.bot"
refused_by "the probe path $tmp/long.bot lasts 1e+07 s: at most 600 s" \
    "$FTM_BENCH" renderers --script "$tmp/long.bot" --delays 0
printf '0 0.06 0.06 0.12\n601 0.06 0.06 0.12\n' >"$tmp/601.bot"
refused_by "lasts 601 s: at most 600 s" "$FTM_BENCH" renderers --script "$tmp/601.bot" --delays 0
# --delays: an empty list or more than 16 is no table
refused_by "--delays must be a comma list of delays in ms, each 0..10000 (got '')" \
    "$FTM_BENCH" renderers --delays ""
refused_by "--delays has more than 16 delays" \
    "$FTM_BENCH" renderers --delays 0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16
refused_by "--delays must be a comma list of delays in ms, each 0..10000 (got '5,x')" \
    "$FTM_BENCH" renderers --delays 5,x
# the option table's parser: positional words and values checked alike
refused_by "unexpected argument 'timings'" "$FTM_BENCH" timings
refused_by "unexpected argument 'all'" "$FTM_BENCH" timing all
refused_by "--path must be press or circle (got 'square')" "$FTM_BENCH" renderers --path square
refused_by "--seconds must be a number of seconds in (0, 3600] (got '0')" "$FTM_BENCH" --seconds 0
refused_by "--repeat must be an integer in 1..100 (got '0')" "$FTM_BENCH" --repeat 0
refused_by "--trace needs a value (FILE), not the option --json" "$FTM_BENCH" --trace --json
# --trace: a path that cannot be written fails at once (it said so and
# exited 0 after the work), nor may it be the --script it reads
refused_by "--trace $tmp/missing/x.csv: No such file or directory" \
    "$FTM_BENCH" renderers --delays 0 --trace "$tmp/missing/x.csv"
refused_by "--trace $tmp: Is a directory" "$FTM_BENCH" renderers --delays 0 --trace "$tmp"
sum=$(cksum "$tmp/601.bot")
refused_by "--trace $tmp/601.bot is the file --script $tmp/601.bot reads" \
    "$FTM_BENCH" renderers --script "$tmp/601.bot" --delays 0 --trace "$tmp/601.bot"
[ "$(cksum "$tmp/601.bot")" = "$sum" ] || fail "--trace overwrote the --script file"
# a run refused after --trace was opened leaves an earlier trace as it was
printf 'an earlier trace\n' >"$tmp/old.csv"
refused_by "lasts 601 s: at most 600 s" \
    "$FTM_BENCH" renderers --script "$tmp/601.bot" --delays 0 --trace "$tmp/old.csv"
[ "$(cat "$tmp/old.csv")" = "an earlier trace" ] || fail "a refused run emptied the earlier --trace"
exit 0
