#!/bin/sh
# Runs the neighbour benchmark of tessel (bench_kdtree) and of nanoflann
# (bench_nanoflann, same data) one after the other and prints one table:
# build seconds and queries/s for both, and ours/nanoflann (> 1: tessel
# faster; for build time, nanoflann's time / ours).
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
[ -x "$theirs" ] || { echo "$0: $theirs not built (nanoflann or C++ missing)" >&2; exit 1; }

out=$(mktemp)
trap 'rm -f "$out"' EXIT
"$ours" "$@" | tee /dev/stderr | grep '^RESULT' >"$out"
"$theirs" "$@" | tee /dev/stderr | grep '^RESULT' >>"$out"

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
    nk = split("build knn8_1t knn8_mt knn16_1t knn16_mt knn32_1t knn32_mt radius_1t radius_mt", keys, " ")
    printf "\n%-20s %-10s", "data", "points"
    for (j = 1; j <= nk; j++) printf " %27s", keys[j] " ours/nano=ratio"
    printf "\n"
    for (i = 1; i <= count; i++) {
        name = order[i]; a = line["tessel", name]; b = line["nanoflann", name]
        if (a == "" || b == "") continue
        printf "%-20s %-10s", name, field(a, "n")
        for (j = 1; j <= nk; j++) {
            x = field(a, keys[j]); y = field(b, keys[j])
            if (keys[j] == "build") r = (x > 0) ? y / x : 0
            else r = (y > 0) ? x / y : 0
            if (keys[j] == "build") cell = sprintf("%.3f/%.3f=%.2f", x, y, r)
            else cell = sprintf("%.0fk/%.0fk=%.2f", x / 1000, y / 1000, r)
            printf " %27s", cell
        }
        same = (field(a, "checksum16") == field(b, "checksum16")) ? "same k=16 distances" : "k=16 distances DIFFER"
        printf "  %s\n", same
    }
}' "$out"
