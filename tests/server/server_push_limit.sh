#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# The probe push limit (--max-penetration, docs/server.md "Collision"),
# offline so no DDS is involved. A trainee's HIP that jumps 1 km into the
# default scene (1728 nodes, 0.11 m across, top face at z = 0.11 m):
#  - with the default limit (the scene's size) the push is shortened to
#    0.11 m, said once in the log and counted; no tick resets the tissue,
#    and the reaction force settles to that of a deep push (a gentle press
#    to 0.11 m ends near 13.5 N; this one may ring at first, from the jump);
#  - with the limit lifted (--max-penetration 1e9) the same input makes a
#    step the guard cannot save and the tissue is reset, which is what the
#    limit is for;
#  - an ordinary 4 mm press is not touched by the default limit.
set -u
fail() { echo "FAIL: $*"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cat >"$tmp/deep.bot" <<'BOT'
0.0 0.035 0.035 0.12
0.5 0.035 0.035 0.12
1.0 0.035 0.035 -999.89
2.0 0.035 0.035 -999.89
BOT
run() { # name options...
    name=$1
    shift
    timeout 60 "$FTM_SERVER" --offline 1500 --reactions "$tmp/$name.csv" "$@" \
        >"$tmp/$name.out" 2>"$tmp/$name.err" || fail "$name: ftm-server exited with $?: $(tail -3 "$tmp/$name.err")"
}
# reaction magnitude on the last line of a reactions CSV (tick,participant,probe,fx,fy,fz)
last() { tail -1 "$1" | awk -F, '{ printf "%.6g", sqrt($4 * $4 + $5 * $5 + $6 * $6) }'; }

run limited --trainee 11:0:"$tmp/deep.bot"
grep -q "probe push limit 0.11 m" "$tmp/limited.err" || fail "the default limit is not the scene's size"
n=$(grep -c "push limited to 0.11 m (--max-penetration)" "$tmp/limited.err")
[ "$n" = 1 ] || fail "the limit was reported $n times in one contact, not once"
grep -q "[1-9][0-9]* probe-ticks with the push limited to 0.11 m; 0 unstable ticks" "$tmp/limited.err" ||
    fail "no count of limited probe-ticks, or unstable ticks: $(grep probe-ticks "$tmp/limited.err")"
! grep -q "tissue reset to rest" "$tmp/limited.err" || fail "the tissue was reset with the limit on"
grep -q "final tick 1500 hash" "$tmp/limited.out" || fail "no final hash"
p=$(last "$tmp/limited.csv")
awk -v p="$p" 'BEGIN { exit !(p > 5 && p < 30) }' || fail "reaction $p N at the end with the push limited"

run lifted --trainee 11:0:"$tmp/deep.bot" --max-penetration 1e9
grep -q "tissue reset to rest" "$tmp/lifted.err" ||
    fail "without the limit the 1 km push did not reset the tissue (the test no longer shows the limit's use)"

run press --trainee 11:0:"$(dirname "$0")/press-hold.bot"
! grep -q "push limited" "$tmp/press.err" || fail "an ordinary 4 mm press was limited"
p2=$(last "$tmp/press.csv")
awk -v p="$p2" 'BEGIN { exit !(p > 0) }' || fail "the 4 mm press gave no reaction"
echo "PASS push limit: 1 km HIP -> reaction $p N at the end, no reset; lifted: reset; 4 mm press untouched ($p2 N)"
