"""numpy -> mesh -> file -> numpy, and the mesh is valid."""
import os
import subprocess
import json

import numpy as np
import pytest

import tessel
from conftest import fibonacci_sphere, sphere


def test_version():
    assert tessel.__version__.count(".") == 2
    assert os.path.exists(tessel.library_path)


def test_reconstruct_sphere_is_valid(clean_sphere):
    mesh = tessel.reconstruct(clean_sphere)
    assert isinstance(mesh, tessel.Mesh)
    assert mesh.vertices.dtype == np.float64 and mesh.vertices.shape[1] == 3
    assert mesh.faces.dtype == np.uint32 and mesh.faces.shape[1] == 3
    assert mesh.faces.flags.c_contiguous
    s = mesh.summary
    assert s["method"] == "greedy" and s["chosen_by"] == "auto"
    assert s["noise_measured"] and s["noise_ratio"] < 0.3
    assert "clean" in s["reason"]
    assert s["triangles"] == len(mesh.faces) and s["vertices"] == len(mesh.vertices)
    assert s["greedy"]["points_in"] == len(clean_sphere)
    report = tessel.check(mesh, input=clean_sphere)
    assert report["valid"], report
    assert report["nonmanifold_edges"] == 0 and report["orientation_conflicts"] == 0
    assert report["self_intersections"] == 0
    assert report["boundary_edges"] == 0 and report["genus"] == 0
    assert report["euler"] == 2
    assert report["input_points"] == len(clean_sphere)
    assert report["input_as_vertices"] == len(clean_sphere)
    # Greedy projection interpolates: vertices are input points.
    assert report["input_distance_max"] < 1e-6


def test_outward_orientation(sphere_mesh):
    v, f = sphere_mesh
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    assert np.all(np.einsum("ij,ij->i", n, (a + b + c) / 3.0) > 0)


@pytest.mark.parametrize("name,kw", [("m.ply", {}), ("m_ascii.ply", {"ascii": 1}),
                                     ("m.obj", {}), ("m.off", {})])
def test_mesh_file_round_trip(tmp_path, sphere_mesh, name, kw):
    path = tmp_path / name
    tessel.write(sphere_mesh, path, **kw)
    back = tessel.read(path)
    assert isinstance(back, tessel.Mesh)
    np.testing.assert_array_equal(back.faces, sphere_mesh.faces)
    np.testing.assert_array_equal(back.vertices, sphere_mesh.vertices)
    assert tessel.check(back)["valid"]


def test_mesh_stl(tmp_path, sphere_mesh):
    sphere_mesh.write(tmp_path / "m.stl")
    data = (tmp_path / "m.stl").read_bytes()
    assert int.from_bytes(data[80:84], "little") == len(sphere_mesh.faces)


@pytest.mark.parametrize("name", ["c.ply", "c.xyz", "c.csv", "c_ascii.ply"])
def test_cloud_file_round_trip(tmp_path, name):
    pts = sphere(500, seed=4)
    normals = pts / np.linalg.norm(pts, axis=1)[:, None]
    colors = (np.abs(normals) * 255).astype(np.uint8)
    cloud = tessel.Cloud(pts, normals, colors)
    tessel.write(cloud, tmp_path / name, ascii=int("ascii" in name))
    back = tessel.read(tmp_path / name)
    assert isinstance(back, tessel.Cloud)
    np.testing.assert_array_equal(back.xyz, cloud.xyz)
    np.testing.assert_array_equal(back.offset, cloud.offset)
    np.testing.assert_allclose(back.normals, cloud.normals, atol=1e-6)
    np.testing.assert_array_equal(back.colors, colors)


def test_read_kind(tmp_path, sphere_mesh):
    sphere_mesh.write(tmp_path / "m.ply")
    assert isinstance(tessel.read(tmp_path / "m.ply", kind="cloud"), tessel.Cloud)
    assert len(tessel.read(tmp_path / "m.ply", kind="cloud")) == len(sphere_mesh.vertices)
    tessel.write(sphere_mesh.vertices, tmp_path / "p.ply")
    assert isinstance(tessel.read(tmp_path / "p.ply"), tessel.Cloud)
    m = tessel.read(tmp_path / "p.ply", kind="mesh")
    assert isinstance(m, tessel.Mesh) and len(m.faces) == 0
    tessel.write(sphere_mesh.vertices, tmp_path / "p.obj")
    assert isinstance(tessel.read(tmp_path / "p.obj"), tessel.Cloud)


def test_pairs_for_other_libraries(sphere_mesh, tmp_path):
    v, f = sphere_mesh  # trimesh.Trimesh(*mesh), meshio, pyvista
    assert v.shape == (len(sphere_mesh.xyz), 3) and f is sphere_mesh.faces
    # A (vertices, faces) pair wherever a mesh is taken.
    assert tessel.check((v, f.astype(np.int64)))["valid"]
    tessel.write((v, f), tmp_path / "pair.ply")
    np.testing.assert_array_equal(tessel.read(tmp_path / "pair.ply").faces, f)
    m = tessel.Mesh(v, f)
    assert tessel.check(m)["valid"]


def test_result_arrays_outlive_the_mesh():
    faces = tessel.reconstruct(fibonacci_sphere(1500), method="greedy").faces
    import gc
    gc.collect()
    assert faces.max() < 1500 and faces.sum() > 0
    faces[0, 0] = faces[0, 0]  # writable


def test_same_as_the_command_line(tmp_path):
    cli = os.environ.get("TESSEL_CLI")
    if not cli or not os.path.exists(cli):
        pytest.skip("TESSEL_CLI not set (run through ctest)")
    pts = sphere(3000, seed=9)
    tessel.write(pts, tmp_path / "in.ply")
    out = subprocess.run([cli, "reconstruct", str(tmp_path / "in.ply"), str(tmp_path / "out.ply"),
                          "--json"], check=True, stdout=subprocess.PIPE, text=True).stdout
    summary = json.loads(out)
    mesh = tessel.reconstruct(tessel.read(tmp_path / "in.ply"))
    assert mesh.summary["method"] == summary["method"] == "greedy"
    assert mesh.summary["triangles"] == summary["triangles"]
    cli_mesh = tessel.read(tmp_path / "out.ply")
    np.testing.assert_array_equal(cli_mesh.faces, mesh.faces)
    np.testing.assert_array_equal(cli_mesh.vertices, mesh.vertices)
    # The same points given as numpy give the same mesh.
    again = tessel.reconstruct(pts)
    np.testing.assert_array_equal(again.faces, mesh.faces)
