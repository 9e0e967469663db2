#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# `ftm bench peers --scene tiny` (docs/peers.md): the JSON parses and holds
# every scene's figures; Bullet's static displacement of the loaded nodes is
# FTM's springs' within 0.1 % (the stiffness was matched) and its whole field
# within 10 %, at Bullet's default solver iterations (1); bad options are
# refused with status 2; --save writes the table and the JSON; --plot draws
# a PNG when gnuplot is there. Exit 77
# (skipped) when ftm was built without Bullet.
set -u
: "${FTM:?}"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm-bench-peers.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
"$FTM" bench peers --scene tiny --rounds 2 --json >"$tmp/out" 2>"$tmp/err" ||
    { echo "FAIL: exit $?"; cat "$tmp/err"; exit 1; }
python3 - "$tmp/out" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
if d["bullet"] is None:
    print("SKIP: ftm built without Bullet")
    sys.exit(77)
[s] = d["scenes"]
print(f"tiny: FTM {s['ftm_us']} us, Bullet {s['bullet_us']} us (x{s['ratio']}); loaded "
      f"displacement {s['ftm_disp']:.4e} / {s['bullet_disp']:.4e} m ({s['disp_diff']:+.1e}), "
      f"field {s['field_diff']:.3f}, kLST scale {s['klst_scale']}")
assert s["scene"] == "tiny" and s["nodes"] == 64 and s["links"] == 360, s
for k in ("ftm_us", "bullet_us", "ftm_linear_us", "ftm_corot_us", "bullet_world_us"):
    assert s[k] > 0, k
assert abs(s["ratio"] - s["bullet_us"] / s["ftm_us"]) <= 1e-3 * s["ratio"], s
assert abs(s["corot_ratio"] - s["bullet_us"] / s["ftm_corot_us"]) <= 1e-3 * s["corot_ratio"], s
assert s["matched"] and abs(s["disp_diff"]) <= 1e-3, s
assert abs(s["bullet_disp"] / s["ftm_disp"] - 1 - s["disp_diff"]) < 1e-6, s
assert s["ftm_disp"] > 0 and s["field_diff"] < 0.1, s
assert s["bullet_iterations"] == 1, s
assert 0 < s["klst_max"] <= 1 and 0.5 < s["klst_scale"] < 2, s
PY
rc=$?
[ $rc -eq 0 ] || exit $rc
"$FTM" bench peers --scene ball >/dev/null 2>"$tmp/err"
[ $? -eq 2 ] && grep -q -- "--scene must be" "$tmp/err" || { echo "FAIL: --scene ball"; exit 1; }
"$FTM" bench peers --rounds 0 >/dev/null 2>"$tmp/err"
[ $? -eq 2 ] && grep -q -- "--rounds" "$tmp/err" || { echo "FAIL: --rounds 0"; exit 1; }
"$FTM" bench peers --scene tiny --save "$tmp/no/such/dir/p" >/dev/null 2>"$tmp/err"
[ $? -eq 2 ] && grep -q "no/such/dir/p.txt: cannot write" "$tmp/err" ||
    { echo "FAIL: --save to a missing directory"; exit 1; }
"$FTM" bench peers --scene tiny --rounds 1 --save "$tmp/p" >/dev/null 2>&1 &&
    python3 -c 'import json, sys; json.load(open(sys.argv[1]))' "$tmp/p.json" &&
    grep -q '^tiny ' "$tmp/p.txt" || { echo "FAIL: --save"; exit 1; }
if command -v gnuplot >/dev/null 2>&1; then
    "$FTM" bench peers --scene tiny --rounds 1 --plot "$tmp/peers.png" >/dev/null 2>"$tmp/err" ||
        { echo "FAIL: --plot: exit $?"; cat "$tmp/err"; exit 1; }
    [ -s "$tmp/peers.png" ] || { echo "FAIL: --plot drew nothing"; exit 1; }
fi
echo "PASS"
