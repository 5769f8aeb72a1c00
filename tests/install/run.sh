#!/bin/sh
# Installs the build into a temporary prefix, then builds and runs a tiny
# program against it with the CMake package (shared and static) and with
# pkg-config. Usage: run.sh SOURCE_DIR BUILD_DIR
set -eu
src=$1
build=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
cmake -S "$src/tests/install" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/consumer" >/dev/null
LD_LIBRARY_PATH="$tmp/prefix/lib:$tmp/prefix/lib64:${LD_LIBRARY_PATH:-}" "$tmp/consumer/consumer"
"$tmp/consumer/consumer_static"
if command -v pkg-config >/dev/null 2>&1; then
    pc=$(find "$tmp/prefix" -name tessel.pc -print -quit)
    flags=$(PKG_CONFIG_PATH=$(dirname "$pc") pkg-config --cflags --libs tessel)
    ${CC:-cc} "$src/tests/install/consumer.c" -o "$tmp/pc_consumer" $flags
    LD_LIBRARY_PATH="$tmp/prefix/lib:$tmp/prefix/lib64:${LD_LIBRARY_PATH:-}" "$tmp/pc_consumer"
else
    echo "pkg-config not installed: skipped the pkg-config check" >&2
fi
echo "1 passed, 0 failed"
