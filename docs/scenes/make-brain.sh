#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
# Meshes the brain of brain.scene from Debian's mricron-data: the Colin27
# brain ch2bet.nii.gz (skull stripped) and the AAL atlas aal.nii.gz, both on
# the same 181 x 217 x 181 grid of 1 mm voxels. Grey matter: every voxel
# AAL labels (its 116 regions, values 2001-9170); white matter: the rest of
# the brain, the voxels of ch2bet above 0 that AAL leaves at 0. ftm mesh
# (CGAL's Mesh_3, a fixed seed: the same file every run) writes brain.msh
# beside this script, in the scan's frame in metres, grey matter physical
# group 1 and white matter 2. docs/meshes.md ("A brain from a scan").
set -eu
here=$(cd "$(dirname "$0")" && pwd)
data=${MRICRON_DATA:-/usr/share/mricron/templates}
ftm=${FTM:-$(cd "$here/../.." && pwd)/build/release/tools/ftm}
[ -x "$ftm" ] || ftm=ftm
for f in aal.nii.gz ch2bet.nii.gz; do
    [ -r "$data/$f" ] || { echo "make-brain.sh: $data/$f not found (Debian: apt-get install mricron-data)" >&2; exit 2; }
done
"$ftm" mesh "$data/aal.nii.gz" --tissue grey=1-9170 --tissue white=0 \
    --mask "$data/ch2bet.nii.gz" --above 0 -o "$here/brain.msh" "$@"
