#!/bin/sh
# The README's first command ends here: reconstruct the bundled bunny scan,
# check the mesh and render cloud and mesh to PNG in demo/.
set -eu
build=${1:-build}
cd "$(dirname "$0")/.."
tessel="$build/tessel"
mkdir -p demo
"$tessel" info data/bunny.ply
"$tessel" reconstruct data/bunny.ply demo/bunny_mesh.ply
"$tessel" check demo/bunny_mesh.ply --input data/bunny.ply
"$tessel" render data/bunny.ply demo/bunny_cloud.png --view iso --size 640x480
"$tessel" render demo/bunny_mesh.ply demo/bunny_mesh.png --view iso --size 640x480
echo "demo: wrote demo/bunny_mesh.ply, demo/bunny_cloud.png, demo/bunny_mesh.png"
