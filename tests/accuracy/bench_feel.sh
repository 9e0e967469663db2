#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# `ftm bench feel --quick --json` (docs/feel.md): the JSON parses; the elastic
# far field gives the linear FEM's force at depth 2 where the fixed one is
# over 50 % stiff, and the neo-Hookean force at depth 2 is within 5 % of the
# reference; a bad option is refused with status 2.
set -u
: "${FTM:?}"
out=$(mktemp)
trap 'rm -f "$out"' EXIT
"$FTM" bench feel --quick --json >"$out" || { echo "FAIL: exit $?"; exit 1; }
python3 - "$out" <<'PY' || exit 1
import json, sys
rows = json.load(open(sys.argv[1]))["rows"]
def get(model, far, depth):
    r = [r for r in rows if r["model"] == model and r["far_field"] == far and r["depth"] == depth]
    assert len(r) == 1 and not r[0]["failed"], (model, far, depth)
    return r[0]
e = get("linear-fem", "elastic", 2)
f = get("linear-fem", "fixed", 2)
n = get("neo-hookean", "elastic", 2)
print(f"linear-fem depth 2: elastic {e['force_error']:+.2e}, fixed {f['force_error']:+.3f}; "
      f"neo-hookean elastic {n['force_error']:+.4f}")
assert abs(e["force_error"]) < 1e-4 and e["dent_error"] < 1e-3, e
assert f["force_error"] > 0.5, f
assert abs(n["force_error"]) < 0.05 and n["dent_error"] < 0.1, n
assert all(r["step_us"] > 0 and r["settled"] for r in rows if not r["failed"])
PY
"$FTM" bench feel --max-steps 12 >/dev/null 2>&1
[ $? -eq 2 ] || { echo "FAIL: --max-steps 12 not refused with status 2"; exit 1; }
echo "PASS"
