#!/bin/sh
# Runs every fuzzer built in BUILD_DIR for SECONDS each on its corpus in
# fuzz/corpus/<name>/ (new finds go to a scratch folder, not the repo). An
# input that runs over 20 s is a find too (a hang), instead of libFuzzer's
# default 20 minutes.
# Usage: run.sh BUILD_DIR SECONDS
set -eu
build=$1
seconds=$2
here=$(cd "$(dirname "$0")" && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
status=0
for bin in "$build"/fuzz/fuzz_*; do
    [ -x "$bin" ] || continue
    fmt=$(basename "$bin" | sed 's/^fuzz_//')
    mkdir -p "$scratch/$fmt"
    echo "fuzz_$fmt: ${seconds}s"
    if ! "$bin" -max_total_time="$seconds" -timeout=20 -max_len=65536 -rss_limit_mb=2048 \
        -artifact_prefix="$here/artifacts-$fmt-" -print_final_stats=0 \
        "$scratch/$fmt" "$here/corpus/$fmt" >"$scratch/$fmt.log" 2>&1; then
        tail -40 "$scratch/$fmt.log"
        status=1
    fi
done
exit $status
