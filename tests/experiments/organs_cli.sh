#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# `ftm experiment organs` end to end (paper 4.4, docs/experiments.md): a
# quick run of the generated stomach and lung pressed by a probe, the OBJ
# and scene files it writes (and docs/scenes' copies) loaded by `ftm sim`,
# the outputs, and the refusals of bad options.
# Environment: FTM = path to the ftm binary; FTM_SOURCE_DIR = the source tree
# (for docs/scenes). Needs python3 (reads the JSON).
set -eu

: "${FTM:?set FTM to the ftm binary}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_organs.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(cd "$(dirname "$0")" && pwd)/../check.sh" # run, check, json, exit2_naming

# the last run: succeeded and said nothing of a warning; its output lacks TEXT
clean_run() { [ "$rc" -eq 0 ] && ! grep -qi warn "$tmp/err"; }
no_output() { ! grep -q -- "$1" "$tmp/out"; }


# --- a quick run ----------------------------------------------------------------

run experiment organs --quick --max-depth 3 --steps 20 --json
check "the quick run succeeds (exit 0)" [ "$rc" -eq 0 ]
check "the paper's counts" json '[(o["name"], o["nodes"], o["triangles"]) for o in d["organs"]] ==
    [("lung", 1769, 3534), ("stomach", 512, 1020)]'
check "closed, oriented, well-shaped surfaces" json 'all(o["quality"]["ok"] and
    o["quality"]["open_edges"] == 0 and o["quality"]["misoriented_edges"] == 0 and
    o["quality"]["degenerate"] == 0 and o["quality"]["inverted"] == 0 and
    o["quality"]["euler"] == 2 and o["edges"] == 3 * o["triangles"] // 2 and
    o["links"] == o["edges"] and o["quality"]["min_angle_deg"] >= 20 for o in d["organs"])'
check "the simulation did not warn (stable at h = 1 ms)" \
    json 'all(o["warnings"] == 0 and o["critical_time_step"] > d["time_step"] for o in d["organs"])'
check "depths 1..3 and the whole organ" \
    json 'all([r["depth"] for r in o["rows"]] == [1, 2, 3, o["full_depth"]] and
    o["rows"][-1]["whole_organ"] and o["rows"][-1]["region_nodes"] == o["nodes"] for o in d["organs"])'
check "the region grows with depth" json 'all(all(a["region_nodes"] < b["region_nodes"]
    for a, b in zip(o["rows"], o["rows"][1:])) for o in d["organs"])'
check "the probe feels a reaction force, pushing it out" \
    json 'all(r["reaction_normal_n"] > 0 for o in d["organs"] for r in o["rows"])'
check "the pressed vertices moved by the press" \
    json 'all(abs(r["max_disp_mm"] - d["press_mm"]) < 1e-6 for o in d["organs"] for r in o["rows"])'
check "step times and the 1 kHz verdict are reported" json 'all(r["step_search_us"] > 0 and
    r["step_cached_us"] > 0 and r["haptic_1khz"] in (True, False) for o in d["organs"] for r in o["rows"])'
check "the shape change is measured below the whole organ" \
    json 'all(r["change"] is not None and r["change"] >= 0 for o in d["organs"] for r in o["rows"][:-1])'
check "no picture without --out" json 'd["png"] is None'

run experiment organs --organ stomach --quick --max-depth 2 --steps 10
check "the table" grep -q '^stomach: 512 nodes, 1020 triangles (paper: 512 / 1020)' "$tmp/out"
check "the table has no lung" no_output '^lung'
check "the table reports no warning" grep -q 'no warning' "$tmp/out"

# --- files: OBJ and scenes, CSV, pictures -----------------------------------------------

mkdir "$tmp/obj" "$tmp/out_dir"
rc=0
FTM_GNUPLOT="$tmp/no-gnuplot" "$FTM" experiment organs --organ stomach --quick --max-depth 2 \
    --steps 10 --obj "$tmp/obj" --out "$tmp/out_dir" --json >"$tmp/out" 2>"$tmp/err" || rc=$?
check "--obj and --out without gnuplot succeed" [ "$rc" -eq 0 ]
check "it says the picture is skipped" grep -q 'gnuplot not found: no picture' "$tmp/err"
check "no picture is claimed" json 'd["png"] is None'
check "it writes the CSV" grep -q '^organ,depth,region_nodes,' "$tmp/out_dir/organs_depth.csv"
check "it writes the surfaces and the script" test -s "$tmp/out_dir/organs_stomach_pressed.dat" \
    -a -s "$tmp/out_dir/organs.gp"
check "the OBJ has the paper's counts" \
    test "$(grep -c '^v ' "$tmp/obj/stomach.obj") $(grep -c '^f ' "$tmp/obj/stomach.obj")" = "512 1020"
run sim "$tmp/obj/stomach-surface.scene" --steps 300 --json
check "the written scene runs" [ "$rc" -eq 0 ]
check "its mesh is the stomach and its probe felt a force" json 'd["nodes"] == 512 and
    any(abs(g["force"][0]) + abs(g["force"][1]) + abs(g["force"][2]) > 0 for g in d["reactions"])'
check "it did not warn" clean_run

if [ -n "${FTM_SOURCE_DIR:-}" ]; then
    for organ in stomach lung stomach-surface lung-surface; do
        run sim "$FTM_SOURCE_DIR/docs/scenes/$organ.scene" --steps 200
        check "docs/scenes/$organ.scene runs without a warning" \
            clean_run
    done
    check "docs/scenes/stomach.obj is what the generator writes now" \
        cmp -s "$FTM_SOURCE_DIR/docs/scenes/stomach.obj" "$tmp/obj/stomach.obj"
    check "docs/scenes/stomach-surface.scene is what the generator writes now" \
        cmp -s "$FTM_SOURCE_DIR/docs/scenes/stomach-surface.scene" "$tmp/obj/stomach-surface.scene"
    # the training organs: tetrahedra filling the surfaces, felt in palpation's range
    for organ in stomach lung; do
        run sim "$FTM_SOURCE_DIR/docs/scenes/$organ.scene" --steps 1 --press --json
        check "docs/scenes/$organ.scene keeps the paper's surface" \
            json 'd["triangles"] == {"stomach": 1020, "lung": 3534}["'$organ'"]'
        check "a 7.5 mm press on docs/scenes/$organ.scene gives 1-10 N" \
            json '1.0 <= d["press"]["force"] <= 10.0'
    done
    run sim "$FTM_SOURCE_DIR/docs/scenes/stomach-surface.scene" --steps 1 --press
    check "the paper's surface stomach is called far softer than tissue" \
        grep -q '^press .*far softer than tissue' "$tmp/out"
fi

if command -v gnuplot >/dev/null 2>&1; then
    mkdir "$tmp/png"
    run experiment organs --organ stomach --quick --max-depth 2 --steps 10 --out "$tmp/png" --json
    check "with gnuplot the pictures are claimed" json 'd["png"] is not None'
    check "the pictures are PNGs" python3 -c 'import sys
sys.exit(0 if all(open(p, "rb").read(8) == b"\x89PNG\r\n\x1a\n" for p in sys.argv[1:]) else 1)' \
        "$tmp/png/organs.png" "$tmp/png/organs_depth.png"
else
    echo "skip the pictures: no gnuplot"
fi

mkdir "$tmp/full"
ln -s /dev/full "$tmp/full/organs_depth.csv"
run experiment organs --organ stomach --quick --max-depth 2 --steps 10 --out "$tmp/full"
check "a CSV file on /dev/full exits 2 naming it" exit2_naming 'full/organs_depth.csv: cannot write'

# --- refusals ----------------------------------------------------------------------

for bad in "--press 0" "--press 51" "--press x" "--max-depth 0" "--max-depth 41" "--steps 5" \
    "--threshold 1" "--organ liver" "--out $tmp/no/such" "--obj $tmp/no/such"; do
    # shellcheck disable=SC2086 # option and value split on purpose
    run experiment organs $bad
    opt=${bad%% *}
    check "$opt ${bad#* } exits 2 naming $opt" exit2_naming "$opt"
done
run experiment organs --press
check "--press without a value exits 2" exit2_naming '--press needs a value'
run experiment organs --bogus
check "an unknown option exits 2" exit2_naming "unknown option '--bogus'"
run experiment organs stray
check "a stray argument exits 2" exit2_naming "unexpected argument 'stray'"
run experiment --quick organs
check "depth's options before organs exit 2" exit2_naming 'organs takes its own options'
run experiment organs --help
check "--help exits 0" [ "$rc" -eq 0 ]
check "--help shows the usage" grep -q '^usage: ftm experiment organs' "$tmp/out"

check_summary
