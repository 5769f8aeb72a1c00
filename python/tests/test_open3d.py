"""Mesh.to_open3d / Cloud.to_open3d / tessel.from_open3d: with Open3D when it
is installed (Debian python3-open3d), and always against a stand-in module
with the few parts of Open3D's API the conversions use."""
import sys
import types

import numpy as np
import pytest

import tessel
from conftest import fibonacci_sphere


def _fake_open3d():
    o3d = types.ModuleType("open3d")
    o3d.utility = types.SimpleNamespace()
    o3d.geometry = types.SimpleNamespace()

    class Vector(np.ndarray):
        def __new__(cls, a):
            return np.array(a).view(cls)

    o3d.utility.Vector3dVector = lambda a: Vector(np.asarray(a, dtype=np.float64))
    o3d.utility.Vector3iVector = lambda a: Vector(np.asarray(a, dtype=np.int32))
    empty = np.empty((0, 3))

    class PointCloud:
        def __init__(self, points=None):
            self.points = empty if points is None else points
            self.normals = empty
            self.colors = empty

        def has_normals(self):
            return len(self.normals) > 0

        def has_colors(self):
            return len(self.colors) > 0

    class TriangleMesh:
        def __init__(self, vertices=None, triangles=None):
            self.vertices = vertices
            self.triangles = triangles
            self.vertex_normals = empty
            self.vertex_colors = empty

        def has_vertex_normals(self):
            return len(self.vertex_normals) > 0

        def has_vertex_colors(self):
            return len(self.vertex_colors) > 0

    o3d.geometry.PointCloud = PointCloud
    o3d.geometry.TriangleMesh = TriangleMesh
    return o3d


def _real_open3d():
    try:
        import open3d
    except ImportError:
        return None
    return open3d


@pytest.fixture(params=["stand-in", "open3d"])
def o3d(request, monkeypatch):
    if request.param == "stand-in":
        fake = _fake_open3d()
        monkeypatch.setitem(sys.modules, "open3d", fake)
        return fake
    real = _real_open3d()
    if real is None:
        pytest.skip("open3d not installed (apt-get install python3-open3d)")
    return real


def test_mesh_round_trip(o3d, sphere_mesh):
    m = sphere_mesh.to_open3d()
    assert isinstance(m, o3d.geometry.TriangleMesh)
    np.testing.assert_array_equal(np.asarray(m.vertices), sphere_mesh.vertices)
    np.testing.assert_array_equal(np.asarray(m.triangles), sphere_mesh.faces)
    back = tessel.from_open3d(m)
    assert isinstance(back, tessel.Mesh)
    np.testing.assert_array_equal(back.faces, sphere_mesh.faces)
    np.testing.assert_array_equal(back.vertices, sphere_mesh.vertices)
    assert tessel.check(back)["valid"]


def test_cloud_round_trip(o3d):
    pts = fibonacci_sphere(800) + 1e6
    colors = np.tile(np.array([[10, 200, 255]], np.uint8), (800, 1))
    cloud = tessel.Cloud(pts, normals=fibonacci_sphere(800), colors=colors)
    pcd = cloud.to_open3d()
    assert isinstance(pcd, o3d.geometry.PointCloud) and pcd.has_normals() and pcd.has_colors()
    np.testing.assert_array_equal(np.asarray(pcd.points), cloud.points)
    back = tessel.from_open3d(pcd)
    assert isinstance(back, tessel.Cloud)
    np.testing.assert_array_equal(back.xyz, cloud.xyz)
    np.testing.assert_array_equal(back.offset, cloud.offset)
    np.testing.assert_array_equal(back.colors, colors)
    mesh = tessel.reconstruct(back)
    assert mesh.colors is not None and tessel.check(mesh)["valid"]


def test_from_open3d_rejects_other_objects(o3d):
    with pytest.raises(TypeError):
        tessel.from_open3d(object())


def test_without_open3d(monkeypatch, sphere_mesh):
    monkeypatch.setitem(sys.modules, "open3d", None)  # import open3d fails
    with pytest.raises(ImportError, match="python3-open3d"):
        sphere_mesh.to_open3d()
