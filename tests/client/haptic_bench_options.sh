#!/bin/sh
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
exit 0
