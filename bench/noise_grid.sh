#!/bin/sh
# The noisy-cloud bench grid: tessel sample of reference meshes at several
# sizes and noise levels, each reconstructed by the given methods, timed as
# whole processes (/usr/bin/time: wall seconds, peak resident memory) and
# measured with tessel check against its reference (boundary edges,
# components, non-manifold elements, self-intersections, F-score at 1% of
# the diagonal). One line per run, tab-separated, on stdout.
#
# Usage: bench/noise_grid.sh BUILD DATA [SIZES] [SIGMAS] [METHODS] [MESHES]
#   BUILD    build folder holding the tessel program
#   DATA     folder holding NAME.gt.ply reference meshes
#   SIZES    default "1e5 1e6 4e6"
#   SIGMAS   noise as fractions of the diagonal, default "0 0.001 0.0025 0.005 0.01"
#   METHODS  default "auto greedy smooth"
#   MESHES   default "bunny elephant knot2"
# Needs /usr/bin/time (Debian package time) and awk. Scratch files go to a
# temporary folder that is removed at the end.
set -eu
build=$1
data=$2
sizes=${3:-"1e5 1e6 4e6"}
sigmas=${4:-"0 0.001 0.0025 0.005 0.01"}
methods=${5:-"auto greedy smooth"}
meshes=${6:-"bunny elephant knot2"}
tessel=$build/tessel
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT INT TERM
printf 'mesh\tpoints\tsigma\tmethod\tchose\tseconds\tpeak_MB\tbytes_per_point\tboundary_pct\tcomponents\tnonmanifold\tself_intersections\tfscore\n'
for mesh in $meshes; do
    ref=$data/$mesh.gt.ply
    for n in $sizes; do
        for s in $sigmas; do
            cloud=$tmp/cloud.ply
            "$tessel" sample "$ref" "$n" "$cloud" --noise-rel "$s" --no-normals --quiet
            for m in $methods; do
                out=$tmp/out.ply
                rm -f "$out"
                /usr/bin/time -f '%e %M' -o "$tmp/time" \
                    "$tessel" reconstruct "$cloud" "$out" --method "$m" --json >"$tmp/summary" \
                    2>/dev/null || true
                read -r secs kb <"$tmp/time"
                chose=$(sed -n 's/.*"method": "\([a-z]*\)".*/\1/p' "$tmp/summary" | head -n 1)
                if [ -s "$out" ]; then
                    "$tessel" check "$out" --ref "$ref" --json --samples 100000 >"$tmp/check" || true
                    get() { sed -n "s/^ *\"$1\": \([^,]*\),*$/\1/p" "$tmp/check" | head -n 1; }
                    edges=$(get edges)
                    bnd=$(get boundary_edges)
                    pct=$(awk -v b="$bnd" -v e="$edges" 'BEGIN { printf "%.4f", (e > 0 ? 100 * b / e : 0) }')
                    nm=$(( $(get nonmanifold_edges) + $(get nonmanifold_vertices) ))
                    mem=$(awk -v k="$kb" -v n="$n" 'BEGIN { printf "%.0f\t%.0f", k / 1024, k * 1024 / n }')
                    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$mesh" "$n" "$s" \
                        "$m" "${chose:-?}" "$secs" "$mem" "$pct" "$(get components)" "$nm" \
                        "$(get self_intersecting_pairs)" "$(get fscore)"
                else
                    printf '%s\t%s\t%s\t%s\t%s\t%s\t-\t-\tfailed\t-\t-\t-\t-\n' "$mesh" "$n" "$s" "$m" \
                        "${chose:-?}" "$secs"
                fi
            done
        done
    done
done
