#!/bin/sh
# The README's first command ends here: describe the bundled scan.
set -eu
build=${1:-build}
cd "$(dirname "$0")/.."
"$build/tessel" info data/bunny.ply
