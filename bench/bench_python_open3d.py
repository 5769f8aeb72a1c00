#!/usr/bin/env python3
"""tessel.reconstruct next to Open3D's ball pivoting and screened Poisson on
the same numpy points, in the same run: seconds and the mesh checks
(tessel.check against the true surface, as `tessel check --ref` measures).

usage: bench/bench_python_open3d.py [--build BUILD] [--points N] [--noise S]

Points: N (default 200,000) uniformly random on a torus (radii 1 and 0.35),
plus Gaussian noise of S (default 0: clean) in world units. Reference: the
torus as a fine parametric mesh. Open3D needs oriented normals: they are
estimated from the 30 nearest neighbours and oriented by its tangent-plane
propagation (k = 30), and that time is counted (tessel needs no normals).
Ball pivoting radii: 1, 2 and 4 times the mean nearest-neighbour spacing;
Poisson depth 9, no density trimming. Needs numpy, open3d (Debian
python3-open3d) and the build's Python package (BUILD/python).
"""
import argparse
import os
import sys
import time


def torus_reference(np, nu=720, nv=288, big=1.0, small=0.35):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    r = big + small * np.cos(v)
    verts = np.column_stack([(r * np.cos(u)).ravel(), (r * np.sin(u)).ravel(),
                             (small * np.sin(v)).ravel()])
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * nv + j).ravel()
    b = (((i + 1) % nu) * nv + j).ravel()
    c = (((i + 1) % nu) * nv + (j + 1) % nv).ravel()
    d = (i * nv + (j + 1) % nv).ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return verts, faces


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default="build")
    ap.add_argument("--points", type=float, default=2e5)
    ap.add_argument("--noise", type=float, default=0.0)
    args = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, os.path.join(os.path.abspath(args.build), "python"))
    sys.path.insert(0, here)
    import numpy as np
    import open3d as o3d
    import tessel
    from bench_python import torus

    n = int(args.points)
    pts = torus(n, seed=2)
    if args.noise:
        pts += np.random.default_rng(3).normal(scale=args.noise, size=pts.shape)
    ref = tessel.Mesh(*torus_reference(np))
    assert tessel.check(ref, self_intersections=0)["boundary_edges"] == 0

    rows = []
    t0 = time.perf_counter()
    mesh = tessel.reconstruct(pts)
    rows.append(("tessel (auto: %s)" % mesh.summary["method"], time.perf_counter() - t0, mesh))

    t0 = time.perf_counter()
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=30))
    pcd.orient_normals_consistent_tangent_plane(30)
    t_normals = time.perf_counter() - t0
    h = tessel.spacing(pts)
    t0 = time.perf_counter()
    bpa = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(
        pcd, o3d.utility.DoubleVector([h, 2 * h, 4 * h]))
    rows.append(("Open3D ball pivoting", t_normals + time.perf_counter() - t0,
                 tessel.from_open3d(bpa)))
    t0 = time.perf_counter()
    poisson, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=9)
    rows.append(("Open3D Poisson (depth 9)", t_normals + time.perf_counter() - t0,
                 tessel.from_open3d(poisson)))

    print("%d points on a torus, noise %g; Open3D's times include its normals (%.2f s)"
          % (n, args.noise, t_normals))
    print("%-26s %8s %9s %6s %9s %9s %7s %7s %9s %7s %7s" % (
        "method", "seconds", "triangles", "valid", "boundary", "nonmanif", "selfint",
        "F-score", "chamfer", "NC", "genus"))
    for name, secs, m in rows:
        r = tessel.check(m, reference=ref, samples=100000)
        print("%-26s %8.2f %9d %6s %9d %9d %7s %7.2f %9.2e %7.4f %7d" % (
            name, secs, r["triangles"], r["valid"], r["boundary_edges"],
            r["nonmanifold_edges"] + r["nonmanifold_vertices"],
            r["self_intersections"], r["fscore"], r["chamfer"], r["normal_consistency"],
            r["genus"]))
    print("valid: manifold, oriented, no self-intersection, duplicate or degenerate triangle; "
          "F-score at 1% of the diagonal; NC: normal consistency")


if __name__ == "__main__":
    main()
