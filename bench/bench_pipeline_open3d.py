#!/usr/bin/python3
"""Open3D's screened Poisson reconstruction (depth 9) of a noisy cloud, the
peer row of bench_pipeline_cgal (which runs this script with the system's
python3 and measures the mesh with tessel_mesh_check).

Normals: estimated from the 30 nearest neighbours and oriented with Open3D's
tangent-plane propagation (k = 30), since the noisy scans carry none. No
density trimming: Poisson's output as it comes.

usage: bench_pipeline_open3d.py IN.ply OUT.ply
Prints the seconds of normal estimation + reconstruction (reading and
writing excluded) on stdout.
"""
import sys
import time

import open3d as o3d


def main():
    if len(sys.argv) != 3:
        sys.stderr.write("usage: bench_pipeline_open3d.py IN.ply OUT.ply\n")
        return 1
    pcd = o3d.io.read_point_cloud(sys.argv[1])
    if len(pcd.points) == 0:
        sys.stderr.write("bench_pipeline_open3d.py: no points in %s\n" % sys.argv[1])
        return 1
    t0 = time.perf_counter()
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=30))
    pcd.orient_normals_consistent_tangent_plane(30)
    mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pcd, depth=9)
    secs = time.perf_counter() - t0
    if not o3d.io.write_triangle_mesh(sys.argv[2], mesh):
        sys.stderr.write("bench_pipeline_open3d.py: cannot write %s\n" % sys.argv[2])
        return 1
    print("%.6f" % secs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
