#!/bin/sh
# Runs the neighbour benchmark of tessel (bench_kdtree) and of nanoflann
# (bench_nanoflann, same data) and prints one table: build seconds and
# queries/s for both, and the ratio (> 1: tessel faster; for the build,
# nanoflann's time / ours). The two programs alternate data set by data set,
# never at the same time, so a change in machine load hits both alike.
# One-thread figures are CPU time (robust to other jobs on the machine),
# threaded ones wall time.
#
# Usage: bench/run_neighbours.sh BUILD_DIR [--max-n N] [--queries Q] [FILE.ply...]
set -eu
if [ $# -lt 1 ]; then
    echo "usage: $0 BUILD_DIR [--max-n N] [--queries Q] [FILE.ply...]" >&2
    exit 2
fi
build=$1
shift
ours=$build/bench/bench_kdtree
theirs=$build/bench/bench_nanoflann
[ -x "$ours" ] || { echo "$0: $ours not built" >&2; exit 1; }
[ -x "$theirs" ] || { echo "$0: $theirs not built (configure with -DTESSEL_BENCH_PEERS=ON; needs nanoflann and C++)" >&2; exit 1; }

max_n=10000000
queries=1000000
files=""
while [ $# -gt 0 ]; do
    case $1 in
    --max-n) max_n=$2; shift 2 ;;
    --queries) queries=$2; shift 2 ;;
    *) files="$files $1"; shift ;;
    esac
done

out=$(mktemp)
raw=$(mktemp)
trap 'rm -f "$out" "$raw"' EXIT
run_both() {
    for prog in "$ours" "$theirs"; do
        "$prog" --queries "$queries" "$@" >"$raw"
        grep -v '^RESULT' "$raw" | tail -n +3
        grep '^RESULT' "$raw" >>"$out"
    done
}
echo "each data set: tessel, then nanoflann; build seconds, then queries/s;"
echo "1t: one thread, CPU time; mt: all threads, wall time"
printf "%-22s %10s %8s %8s %9s %9s %9s %9s %9s %9s %9s %9s\n" data points "build 1t" "build" \
    "k8 1t" "k8 mt" "k16 1t" "k16 mt" "k32 1t" "k32 mt" "rad 1t" "rad mt"
if [ -n "$files" ]; then
    for f in $files; do run_both "$f"; done
else
    n=10000
    while [ "$n" -le "$max_n" ]; do
        run_both --n "$n"
        n=$((n * 10))
    done
fi

awk '
function field(line, key,   n, i, parts, kv) {
    n = split(line, parts, " ")
    for (i = 2; i <= n; i++) {
        split(parts[i], kv, "=")
        if (kv[1] == key) return kv[2]
    }
    return ""
}
{
    impl = field($0, "impl"); name = field($0, "name")
    if (!(name in seen)) { seen[name] = 1; order[++count] = name }
    line[impl, name] = $0
}
END {
    nk = split("build_1t build knn8_1t knn8_mt knn16_1t knn16_mt knn32_1t knn32_mt radius_1t radius_mt", keys, " ")
    printf "\nours / nanoflann = ratio (build: seconds; queries: thousands per second)\n"
    printf "%-20s %-9s", "data", "points"
    for (j = 1; j <= nk; j++) printf " %18s", keys[j]
    printf "\n"
    for (i = 1; i <= count; i++) {
        name = order[i]; a = line["tessel", name]; b = line["nanoflann", name]
        if (a == "" || b == "") continue
        printf "%-20s %-9s", name, field(a, "n")
        for (j = 1; j <= nk; j++) {
            x = field(a, keys[j]); y = field(b, keys[j])
            if (keys[j] ~ /^build/) cell = sprintf("%.3f/%.3f=%.2f", x, y, (x > 0) ? y / x : 0)
            else cell = sprintf("%.0f/%.0f=%.2f", x / 1000, y / 1000, (y > 0) ? x / y : 0)
            printf " %18s", cell
        }
        same = (field(a, "checksum16") == field(b, "checksum16")) ? "same k=16 distances" : "k=16 distances DIFFER"
        printf "  %s\n", same
    }
}' "$out"
