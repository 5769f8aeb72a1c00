#!/usr/bin/env python3
"""What the Python binding costs over the C call (docs/python.md, "Overhead").

usage: bench/bench_python.py [--build BUILD] [--points N] [--runs R] [--method M]

Makes N points (default 10^6) on a torus from a fixed seed, writes them once
as a binary PLY, then R times (default 3), alternating so that the load of
a shared machine falls on both alike:
  - C: BUILD/bench/bench_reconstruct reads the file and times
    tessel_reconstruct alone (the library call, no Python in the process);
  - Python, float32: tessel.reconstruct(points) on a float32 C-contiguous
    array (read in place, no copy), timed around the whole Python call:
    argument checks, the finiteness pass, building the structs, the call,
    wrapping the result, the summary dict;
  - Python, float64: the same points as float64 world coordinates (one
    conversion to float32 + offset, tessel_world_to_local).
Both sides run the same method with default parameters on the same floats
and must give the same number of triangles. Prints the medians, the
overhead of each Python call over the C call, and, within each Python call,
its wall time minus the library's own timing (summary["seconds"]).
Needs numpy and the build's Python package (BUILD/python).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def torus(n, seed=1, big=1.0, small=0.35):
    """n points uniformly distributed over a torus surface (rejection
    sampling of the angle around the tube, which makes the area uniform)."""
    import numpy as np
    rng = np.random.default_rng(seed)
    out = np.empty((0, 3))
    while len(out) < n:
        m = 2 * (n - len(out)) + 1000
        u = rng.uniform(0, 2 * np.pi, m)
        v = rng.uniform(0, 2 * np.pi, m)
        keep = rng.uniform(0, 1, m) < (big + small * np.cos(v)) / (big + small)
        u, v = u[keep], v[keep]
        r = big + small * np.cos(v)
        out = np.vstack([out, np.column_stack([r * np.cos(u), r * np.sin(u), small * np.sin(v)])])
    return out[:n]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default="build")
    ap.add_argument("--points", type=float, default=1e6)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--method", default="auto", choices=["auto", "greedy", "smooth"])
    args = ap.parse_args()
    build = os.path.abspath(args.build)
    sys.path.insert(0, os.path.join(build, "python"))
    import numpy as np
    import tessel

    exe = os.path.join(build, "bench", "bench_reconstruct")
    if not os.path.exists(exe):
        sys.exit("bench_python.py: %s not built (configure with -DTESSEL_BENCH=ON)" % exe)
    n = int(args.points)
    p64 = torus(n)
    p32 = np.ascontiguousarray(p64, dtype=np.float32)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "torus.ply")
        tessel.write(p32, path)
        assert np.array_equal(tessel.read(path).xyz, p32)  # the C side reads the same floats
        c, c_lib, py32, py64, inner32, inner64 = [], [], [], [], [], []
        lib32, lib64 = [], []
        tris = set()
        for r in range(args.runs):
            out = subprocess.run([exe, path, "1", args.method], check=True,
                                 stdout=subprocess.PIPE, text=True).stdout
            res = json.loads(out)
            c.append(res["seconds"][0])
            c_lib.append(res["library_seconds"][0])
            tris.add(res["triangles"])
            for pts, wall, inner, libt in ((p32, py32, inner32, lib32),
                                           (p64, py64, inner64, lib64)):
                t0 = time.perf_counter()
                mesh = tessel.reconstruct(pts, method=args.method)
                wall.append(time.perf_counter() - t0)
                libt.append(mesh.summary["seconds"])
                inner.append(wall[-1] - mesh.summary["seconds"])
                tris.add(len(mesh.faces))
                method = mesh.summary["method"]
                del mesh
            print("run %d: C %.3f s, Python float32 %.3f s, float64 %.3f s"
                  % (r + 1, c[-1], py32[-1], py64[-1]), file=sys.stderr)
    if len(tris) != 1:
        sys.exit("bench_python.py: the C and Python calls made different meshes: %s" % tris)
    med = statistics.median
    print("tessel.reconstruct, %d points on a torus, method %s (%s), %d runs "
          "(wall seconds: median, min; the library's own timing: median):"
          % (n, args.method, method, args.runs))
    print("  %-40s %8.3f %8.3f   library %8.3f" % (
        "C: tessel_reconstruct (bench_reconstruct)", med(c), min(c), med(c_lib)))
    for name, wall, inner, libt in (("Python, float32 array (no copy)", py32, inner32, lib32),
                                    ("Python, float64 array (one conversion)", py64, inner64,
                                     lib64)):
        print("  %-40s %8.3f %8.3f   library %8.3f   over C: median %+.2f%%, min %+.2f%%; "
              "outside the library %.1f ms (%.2f%%)"
              % (name, med(wall), min(wall), med(libt), 100.0 * (med(wall) / med(c) - 1.0),
                 100.0 * (min(wall) / min(c) - 1.0), 1e3 * med(inner),
                 100.0 * med(inner) / med(wall)))
    print("  triangles: %d" % tris.pop())


if __name__ == "__main__":
    main()
