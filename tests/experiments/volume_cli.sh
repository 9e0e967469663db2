#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# `ftm experiment volume` end to end (paper 4.2, docs/experiments.md): the
# synthetic head phantom pressed through a small control lattice, a small
# NIfTI file written here, and the refusals of bad options and files.
# Environment: FTM = path to the ftm binary. Needs python3 (reads the JSON).
set -eu

: "${FTM:?set FTM to the ftm binary}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ftm_test_volume.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(cd "$(dirname "$0")" && pwd)/../check.sh"

# nonempty FILE...: every file exists and is not empty.
nonempty() {
    for f in "$@"; do [ -s "$f" ] || return 1; done
}

# --- the phantom -------------------------------------------------------------

# 7 x 7 x 7: the smallest lattice in which the phantom's skull fixes points
run experiment volume --nodes 7 --json
check "the phantom runs (exit 0)" [ "$rc" -eq 0 ]
check "it reports the 7^3 lattice" json 'd["lattice_points"] == 343 and 0 < d["kept_nodes"] <= 343'
check "air cells are dropped" json 'd["air_cells"] > 0'
check "hard tissue fixes nodes" json 'd["fixed_nodes"] > 0'
check "the press moved the pressed nodes by the push" \
    json 'd["pressed_nodes"] >= 1 and abs(d["pressed_displacement_mm"] - d["push_mm"]) < 1e-6'
check "the press moved the tissue" \
    json 'd["field"]["max_mm"] > 1 and d["field"]["moved_fraction"] > 0'
check "the volume is pressed down, not up" json 'd["field"]["uz_min_mm"] < -1'
check "no fixed node moved" json 'd["fixed_moved"] == 0'
check "equilibrium reached" json 'd["equilibrium"] is True and d["steps"] > 0'
check "the simulation did not warn (stable time step, enough damping)" json 'd["warnings"] == 0'
check "the step stayed below the critical step" json 'd["time_step"] <= d["critical_time_step"]'
check "the FFD puts lattice points on their nodes" json 'd["lattice_match_mm"] < 1e-6'
check "the inverse map converged on the slice" json 'd["slice"]["unmap_residual_mm"] < 1'
check "no picture without --out" json 'd["png"] is None'

run experiment volume --nodes 7
check "the table names the fixed nodes" \
    grep -q '^fixed nodes (hard tissue, faces) *[1-9]' "$tmp/out"
check "the table reports the equilibrium" grep -q '^steps to equilibrium .*(reached)' "$tmp/out"
check "the table reports no fixed node moved" grep -q '^fixed nodes moved *0 (none)' "$tmp/out"

run experiment --json volume --nodes 5 --hard none --fix zmin
check "--json before the name, --hard none, --fix zmin" [ "$rc" -eq 0 ]
check "--fix zmin fixes the bottom's points" json 'd["fixed_nodes"] > 0 and d["fixed_moved"] == 0'

# --- outputs -----------------------------------------------------------------

mkdir "$tmp/nogp"
rc=0
FTM_GNUPLOT="$tmp/no-gnuplot" "$FTM" experiment volume --nodes 5 --out "$tmp/nogp" --json \
    >"$tmp/out" 2>"$tmp/err" || rc=$?
check "without gnuplot the run still succeeds" [ "$rc" -eq 0 ]
check "it says the picture is skipped" grep -q 'gnuplot not found: no picture' "$tmp/err"
check "it writes the nodes' CSV" \
    grep -q '^ix,iy,iz,node,fixed,pressed,' "$tmp/nogp/volume_nodes.csv"
check "it writes the slice data and the script" \
    nonempty "$tmp/nogp/volume_deformed.dat" "$tmp/nogp/volume.gp"
check "no picture is claimed" json 'd["png"] is None'

if command -v gnuplot >/dev/null 2>&1; then
    mkdir "$tmp/png"
    run experiment volume --nodes 5 --plane yz --out "$tmp/png" --json
    check "with gnuplot the run succeeds" [ "$rc" -eq 0 ]
    check "the picture is claimed" json 'd["png"] is not None'
    check "the picture is a PNG" python3 -c 'import sys
sys.exit(0 if open(sys.argv[1], "rb").read(8) == b"\x89PNG\r\n\x1a\n" else 1)' "$tmp/png/volume.png"
else
    echo "skip the picture: no gnuplot"
fi

mkdir "$tmp/gpfail"
rc=0
FTM_GNUPLOT=/bin/false "$FTM" experiment volume --nodes 5 --out "$tmp/gpfail" \
    >"$tmp/out" 2>"$tmp/err" || rc=$?
check "a gnuplot that fails exits 2 (an output not written)" exit2_naming 'failed: no picture'
check "the figures are still printed" grep -q '^steps to equilibrium' "$tmp/out"

mkdir "$tmp/full"
ln -s /dev/full "$tmp/full/volume_nodes.csv"
run experiment volume --nodes 5 --out "$tmp/full"
check "a CSV file on /dev/full exits 2 naming it" \
    exit2_naming 'full/volume_nodes.csv: cannot write: '

run experiment volume --nodes 5 --out "$tmp/no/such/dir"
check "a missing --out directory exits 2" [ "$rc" -eq 2 ]
check "it names --out and the directory" grep -q -- "--out $tmp/no/such/dir" "$tmp/err"

# --- a NIfTI file ------------------------------------------------------------

# 16^3 uint8, 4 mm voxels: a bright block on a soft one, in air
python3 - "$tmp/block.nii" <<'EOF'
import struct, sys
n = 16
hdr = bytearray(348)
struct.pack_into("<i", hdr, 0, 348)                       # sizeof_hdr
struct.pack_into("<8h", hdr, 40, 3, n, n, n, 1, 1, 1, 1)  # dim
struct.pack_into("<hh", hdr, 70, 2, 8)                    # datatype uint8, bitpix
struct.pack_into("<8f", hdr, 76, 1, 4, 4, 4, 1, 1, 1, 1)  # pixdim [mm]
struct.pack_into("<f", hdr, 108, 352)                     # vox_offset
hdr[123] = 2                                              # xyzt_units: mm
hdr[344:348] = b"n+1\0"
data = bytearray(n * n * n)
for k in range(n):
    for j in range(n):
        for i in range(n):
            if 2 <= i < 14 and 2 <= j < 14 and 1 <= k < 13:
                data[i + n * (j + n * k)] = 250 if k < 4 else 120
open(sys.argv[1], "wb").write(bytes(hdr) + b"\0\0\0\0" + bytes(data))
EOF
run experiment volume --volume "$tmp/block.nii" --nodes 5 --json
check "a NIfTI file runs" [ "$rc" -eq 0 ]
check "its voxels are read" json 'd["voxels"] == [16, 16, 16] and abs(d["voxel_mm"][0] - 4) < 1e-9'
check "its bright block is fixed and the press moved the rest" \
    json 'd["fixed_nodes"] > 0 and d["fixed_moved"] == 0 and d["field"]["max_mm"] > 1'

# --- refusals ------------------------------------------------------------------

run experiment volume --nodes 1
check "--nodes 1 exits 2" [ "$rc" -eq 2 ]
check "it names --nodes and the range" grep -q -- '--nodes must be .*2\.\.100' "$tmp/err"

run experiment volume --volume "$tmp/missing.nii"
check "a missing volume file exits 2" [ "$rc" -eq 2 ]
check "it names the file" grep -q "missing.nii" "$tmp/err"

printf 'this is not a NIfTI file, only some text that is long enough ...' >"$tmp/bad.nii"
head -c 400 /dev/zero >>"$tmp/bad.nii"
run experiment volume --volume "$tmp/bad.nii"
check "a malformed volume file exits 2" [ "$rc" -eq 2 ]
check "it names the file" grep -q "bad.nii" "$tmp/err"

for bad in "--depth -1" "--push 0" "--push x" "--hard 2" "--fix top" "--plane xy"; do
    # shellcheck disable=SC2086 # option and value split on purpose
    run experiment volume $bad
    opt=${bad%% *}
    check "$bad exits 2 naming $opt" exit2_naming "$opt"
done
run experiment volume --nodes
check "--nodes without a value exits 2" exit2_naming '--nodes needs a value'
run experiment volume --bogus
check "an unknown option exits 2" exit2_naming "unknown option '--bogus'"
run experiment --quick volume
check "depth's options before volume exit 2" [ "$rc" -eq 2 ]

check_summary
