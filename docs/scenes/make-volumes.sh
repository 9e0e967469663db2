#!/bin/sh
# Fills the paper's section 4.4 organ surfaces (lung.obj, stomach.obj, written
# by `ftm experiment organs --obj`) with tetrahedra for the training scenes
# lung.scene and stomach.scene. TetGen (Debian: tetgen) keeps the surface as
# it is (-Y), so the surface's nodes keep their numbers and the scenes' probe
# loads their nodes; -q1.5 bounds the radius-edge ratio. Writes ORGAN.node
# and ORGAN.ele beside this script.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for organ in stomach lung; do
    awk '/^v /{v[++n]=$2" "$3" "$4} /^f /{split($2,a,"/");split($3,b,"/");split($4,c,"/");f[++m]=(a[1]-1)" "(b[1]-1)" "(c[1]-1)}
         END{print "OFF"; print n, m, 0; for(i=1;i<=n;i++) print v[i]; for(i=1;i<=m;i++) print 3, f[i]}' \
        "$here/$organ.obj" > "$tmp/$organ.off"
    tetgen -pq1.5YQ "$tmp/$organ.off"
    cp "$tmp/$organ.1.node" "$here/$organ.node"
    cp "$tmp/$organ.1.ele" "$here/$organ.ele"
done
