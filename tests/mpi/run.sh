#!/bin/sh
# tessel-mpi against tessel: the same bytes for -np 1..4 and one or two
# threads; a failure on input or output stops every process with a message
# and leaves no file. Usage: run.sh BUILD_DIR MPIEXEC [MPIEXEC_FLAGS...]
set -u
build=$1
shift
here=$(cd "$(dirname "$0")" && pwd)
cloud=$here/../../data/bunny.ply
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM
fails=0
check() { # name, condition exit status
    if [ "$2" -eq 0 ]; then echo "ok   $1"; else echo "FAIL $1"; fails=$((fails + 1)); fi
}
run_mpi() { # np, args...
    np=$1
    shift
    # Open MPI: root in CI containers, more processes than cores.
    flags="--oversubscribe --allow-run-as-root"
    "$MPIEXEC" $flags -np "$np" "$build/tessel-mpi" "$@" >"$work/out" 2>"$work/err"
}
MPIEXEC=$1

# Tiles of 8192 points: the bundled 37,706-point bunny makes 8 of them.
"$build/tessel" reconstruct "$cloud" "$work/ref.ply" --method greedy --tile-points 8192 \
    --quiet
check "tessel writes the reference" $?
"$build/tessel" check "$work/ref.ply" --json >"$work/check.json"
grep -q '"valid": true' "$work/check.json"
check "the reference is valid (manifold, oriented, no self-intersection)" $?
# Each process count once, one or two threads in turn (the meshes do not
# depend on either).
for run in "1 2" "2 1" "3 2" "4 1"; do
    set -- $run
    run_mpi "$1" reconstruct "$cloud" "$work/m.ply" --tile-points 8192 --threads "$2" --quiet
    st=$?
    cmp -s "$work/ref.ply" "$work/m.ply"
    check "-np $1 --threads $2: exit $st, the same bytes as tessel" $(( $? + st ))
    rm -f "$work/m.ply"
done
# Reading in parts: every process's cloud is the one-process read, bit for
# bit (binary PLY with doubles far from the origin, normals, colours and
# NaNs; LAS and LAZ of every point format, COPC in a box; every bad file
# fails alike, with the same message).
python3 - "$work/far.ply" <<'PY'
import math, random, struct, sys
random.seed(3)
n = 5000
with open(sys.argv[1], "wb") as f:
    f.write(b"ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n
            + b"".join(b"property double %s\n" % a for a in (b"x", b"y", b"z"))
            + b"".join(b"property float %s\n" % a for a in (b"nx", b"ny", b"nz"))
            + b"".join(b"property uchar %s\n" % a for a in (b"red", b"green", b"blue"))
            + b"end_header\n")
    for i in range(n):
        t, u = 6.283 * random.random(), 3.1416 * random.random()
        p = [math.cos(t) * math.sin(u), math.sin(t) * math.sin(u), math.cos(u)]
        if i % 977 == 5:
            p[0] = float("nan")
        f.write(struct.pack("<3d3f3B", 512345.25 + 10 * p[0], 4321987.5 + 10 * p[1],
                            100 + 10 * p[2], *p, i % 256, 7 * i % 256, 3))
PY
check "python3 writes the far cloud" $?
for np in 1 2 3 4; do
    "$MPIEXEC" --oversubscribe --allow-run-as-root -np "$np" "$build/test_mpi_read" \
        "$work/far.ply" "$cloud" "$here"/../data/laz/*.la[sz] "$here"/../data/bad/* \
        >"$work/out" 2>"$work/err"
    check "-np $np: clouds read in parts are the one-process reads ($(grep -c '^ok' "$work/out") reads)" $?
done
# Read in parts, the tiles' points (and normals) sent to their processes.
for in in "$here/../data/laz/1.2-with-color.copc.laz" "$work/far.ply"; do
    "$build/tessel" reconstruct "$in" "$work/ref.ply" --method greedy --tile-points 256 --quiet
    for np in 2 3; do
        run_mpi "$np" reconstruct "$in" "$work/m.ply" --tile-points 256 --quiet
        st=$?
        cmp -s "$work/ref.ply" "$work/m.ply"
        check "-np $np, $(basename "$in"): exit $st, the same bytes as tessel" $(( $? + st ))
        rm -f "$work/m.ply"
    done
done

# The smooth method: the front's tiles (256 points: about 40 of the
# bundled bunny's representatives) meshed by the processes.
"$build/tessel" reconstruct "$cloud" "$work/ref.ply" --method smooth --tile-points 256 --quiet
for np in 1 2 3; do
    run_mpi "$np" reconstruct "$cloud" "$work/m.ply" --method smooth --tile-points 256 --quiet
    st=$?
    cmp -s "$work/ref.ply" "$work/m.ply"
    check "-np $np, the smooth method's front in tiles: exit $st, the same bytes as tessel" \
        $(( $? + st ))
    rm -f "$work/m.ply"
done
run_mpi 2 reconstruct "$work/missing.ply" "$work/f.ply" --method smooth
st=$?
[ "$st" -eq 2 ] && grep -q "missing.ply" "$work/err" && [ ! -e "$work/f.ply" ]
check "the smooth method, a missing input: exit $st, named, no output" $?
run_mpi 2 reconstruct "$cloud" "$work/no/such/dir/f.ply" --method smooth --tile-points 256
st=$?
[ "$st" -eq 3 ] && grep -q "f.ply" "$work/err"
check "the smooth method, an output that cannot be written: exit $st, named" $?

# Out of core (--memory 1M: slabs of 1,000 points, each cut into tiles of
# at most 256): each slab's tiles meshed by the processes, the same bytes,
# no scratch file left.
"$build/tessel" reconstruct "$cloud" "$work/ref.ply" --memory 1M --tile-points 256 --quiet
for run in "1 1" "2 1" "3 2"; do
    set -- $run
    run_mpi "$1" reconstruct "$cloud" "$work/m.ply" --memory 1M --tile-points 256 \
        --threads "$2" --json
    st=$?
    cmp -s "$work/ref.ply" "$work/m.ply" && grep -q '"out_of_core": true' "$work/out" &&
        [ "$(grep -c '"tiles"' "$work/out")" -eq 1 ] && ! grep -q '"tiles": 0,' "$work/out"
    check "-np $1 --threads $2, out of core in tiles: exit $st, the same bytes as tessel, one summary" \
        $(( $? + st ))
    rm -f "$work/m.ply"
done
run_mpi 2 reconstruct "$cloud" "$work/f.ply" --memory 1M --tile-points 256 \
    --scratch "$work/no/such/dir"
st=$?
[ "$st" -ne 0 ] && grep -q "no/such/dir" "$work/err" && [ ! -e "$work/f.ply" ]
check "out of core, a scratch folder that cannot be made: exit $st, named, no output" $?

# One tile (the default tile size): every process meshes it whole.
"$build/tessel" reconstruct "$cloud" "$work/one.ply" --method greedy --quiet
run_mpi 3 reconstruct "$cloud" "$work/m.ply" --quiet
st=$?
cmp -s "$work/one.ply" "$work/m.ply"
check "-np 3, one tile: the same bytes" $(( $? + st ))

# Failures: every process stops, the message names the file, no output.
run_mpi 3 reconstruct "$work/missing.ply" "$work/f.ply"
st=$?
[ "$st" -eq 2 ] && grep -q "missing.ply" "$work/err" && [ ! -e "$work/f.ply" ]
check "a missing input: exit $st, named, no output" $?
printf 'ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1\n' \
    >"$work/cut.ply"
run_mpi 2 reconstruct "$work/cut.ply" "$work/f.ply"
st=$?
[ "$st" -eq 2 ] && grep -q "cut.ply" "$work/err" && [ ! -e "$work/f.ply" ]
check "a truncated input: exit $st, named, no output" $?
run_mpi 2 reconstruct "$cloud" "$work/no/such/dir/f.ply"
st=$?
[ "$st" -eq 3 ] && grep -q "f.ply" "$work/err"
check "an output that cannot be written: exit $st, named" $?
run_mpi 2 reconstruct "$cloud" "$work/f.ply" --mu 50
st=$?
[ "$st" -eq 1 ] && [ ! -e "$work/f.ply" ]
check "a bad option: exit $st (usage), no output" $?
left=$(ls -A "$work" | grep -c '^\.') || true
[ "$left" -eq 0 ]
check "no temporary files left" $?

echo "$fails failed"
[ "$fails" -eq 0 ]
