#!/bin/sh
# The scale bench: greedy projection on tessel sample of reference meshes at
# several sizes, on 1 and 2 threads, and (when tessel-mpi is built and
# mpirun found) on 2 MPI processes of one thread. Each run is timed as a
# whole process (/usr/bin/time: wall seconds, peak resident memory of the
# largest process), its mesh compared byte for byte with the first run's
# (the result must not depend on threads or processes), and the summary's
# boundary edges and components reported. One line per run, tab-separated,
# on stdout; the speed-up column is the run's wall time against the same
# cloud's one-thread run. The last runs of each cloud are out of core
# (--memory OOC_MEMORY, default 2G; docs/outofcore.md), on 2 threads and
# (with tessel-mpi) on 2 processes: the first one's mesh differs from the
# in-core ones by construction (same_bytes "-"), and its boundary edges and
# components come from tessel check, with "valid" when the mesh is
# manifold, oriented and free of self-intersections; the processes' mesh
# is compared with it byte for byte.
#
# Usage: bench/scale_grid.sh BUILD DATA [SIZES] [MESHES] [RUNS]
#   BUILD    build folder holding tessel (and tessel-mpi)
#   DATA     folder holding NAME.gt.ply reference meshes
#   SIZES    default "1e5 1e6 1e7"
#   MESHES   default "bunny elephant"
#   RUNS     runs of each command, the median reported; default 3
# Needs /usr/bin/time (Debian package time) and awk. Scratch files go to a
# temporary folder that is removed at the end.
set -eu
build=$1
data=$2
sizes=${3:-"1e5 1e6 1e7"}
meshes=${4:-"bunny elephant"}
runs=${5:-3}
ooc_memory=${OOC_MEMORY:-2G}
tessel=$build/tessel
mpi=""
if [ -x "$build/tessel-mpi" ] && command -v mpirun >/dev/null 2>&1; then
    mpi="mpirun --oversubscribe --allow-run-as-root --bind-to none -np 2 $build/tessel-mpi"
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT INT TERM

# run NAME CMD...: the median wall time and peak memory of RUNS runs of CMD
# writing $tmp/out.ply; sets secs, kb.
run() {
    : >"$tmp/times"
    i=0
    while [ "$i" -lt "$runs" ]; do
        rm -f "$tmp/out.ply"
        /usr/bin/time -f '%e %M' -o "$tmp/time" "$@" >"$tmp/summary" 2>/dev/null || true
        cat "$tmp/time" >>"$tmp/times"
        i=$((i + 1))
    done
    secs=$(sort -n "$tmp/times" | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }')
    kb=$(sort -n -k2 "$tmp/times" | awk '{ a[NR] = $2 } END { print a[int((NR + 1) / 2)] }')
}

printf 'mesh\tpoints\trun\tseconds\tpoints_per_s\tpeak_MB\tbytes_per_point\tspeedup\tsame_bytes\tboundary_edges\tcomponents\n'
for mesh in $meshes; do
    for n in $sizes; do
        cloud=$tmp/cloud.ply
        "$tessel" sample "$data/$mesh.gt.ply" "$n" "$cloud" --no-normals --quiet
        base=""
        rm -f "$tmp/ooc.ply"
        for how in threads1 threads2 mpi2 outofcore outofcore_mpi2; do
            case $how in
            threads1) run "$tessel" reconstruct "$cloud" "$tmp/out.ply" --method greedy --threads 1 --json ;;
            threads2) run "$tessel" reconstruct "$cloud" "$tmp/out.ply" --method greedy --threads 2 --json ;;
            mpi2)
                [ -n "$mpi" ] || continue
                # shellcheck disable=SC2086
                run $mpi reconstruct "$cloud" "$tmp/out.ply" --threads 1 --json
                ;;
            outofcore) run "$tessel" reconstruct "$cloud" "$tmp/out.ply" --method greedy --memory "$ooc_memory" --threads 2 --json ;;
            outofcore_mpi2)
                [ -n "$mpi" ] || continue
                # shellcheck disable=SC2086
                run $mpi reconstruct "$cloud" "$tmp/out.ply" --memory "$ooc_memory" --threads 1 --json
                ;;
            esac
            if [ ! -s "$tmp/out.ply" ]; then
                printf '%s\t%s\t%s\t%s\tfailed\n' "$mesh" "$n" "$how" "$secs"
                continue
            fi
            if [ "$how" = outofcore ]; then
                "$tessel" check "$tmp/out.ply" --json >"$tmp/summary" 2>/dev/null || true
                grep -q '"valid": true' "$tmp/summary" && same="- valid" || same="- INVALID"
                cp "$tmp/summary" "$tmp/ooc_check"
                mv "$tmp/out.ply" "$tmp/ooc.ply"
            elif [ "$how" = outofcore_mpi2 ]; then
                cmp -s "$tmp/out.ply" "$tmp/ooc.ply" && same=yes || same=NO
                cp "$tmp/ooc_check" "$tmp/summary"
            elif [ -z "$base" ]; then
                base=$secs
                mv "$tmp/out.ply" "$tmp/first.ply"
                same=yes
            else
                cmp -s "$tmp/out.ply" "$tmp/first.ply" && same=yes || same=NO
            fi
            get() { sed -n "s/.*\"$1\": \([0-9.]*\).*/\1/p" "$tmp/summary" | head -n 1; }
            awk -v m="$mesh" -v n="$n" -v h="$how" -v s="$secs" -v k="$kb" -v b="$base" \
                -v same="$same" -v be="$(get boundary_edges)" -v c="$(get components)" \
                'BEGIN { printf "%s\t%s\t%s\t%s\t%.0f\t%.0f\t%.0f\t%.2f\t%s\t%s\t%s\n",
                         m, n, h, s, n / s, k / 1024, k * 1024 / n, b / s, same, be, c }'
        done
    done
done
