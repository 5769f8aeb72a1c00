"""float64 georeferenced coordinates (offsets of 1e5 to 1e6) survive to the
output: the same offset and floats as the file readers choose."""
import numpy as np
import pytest

import tessel
from conftest import fibonacci_sphere, terrain

UTM = np.array([512345.0, 4649776.0, 231.0])


def _rows(a):
    a = np.ascontiguousarray(a, dtype=np.float64)
    return {r.tobytes() for r in a}


def test_exact_world_coordinates_survive_reconstruction():
    # Coordinates on a 2^-12 grid (about 0.24 mm) around UTM values: exact in
    # float64, and exact as float32 in any frame within 4096 of the data.
    local = np.round(terrain(nx=60, ny=50, step=2.0) * 4096.0) / 4096.0
    world = local + UTM
    mesh = tessel.reconstruct(world, method="height")
    assert mesh.summary["method"] == "height"
    assert np.all(mesh.offset != 0) or mesh.offset[2] == 0
    assert mesh.offset[0] >= 500000 and mesh.offset[1] >= 4e6
    v = mesh.vertices
    assert len(v) > 0.25 * len(world)  # one representative per dexel
    # Every output vertex is an input point, bit for bit.
    assert _rows(v) <= _rows(world)
    assert tessel.check(mesh)["valid"]


def test_exact_through_a_file(tmp_path):
    world = np.round(fibonacci_sphere(3000, radius=20.0) * 4096.0) / 4096.0 + UTM
    mesh = tessel.reconstruct(world, method="greedy")
    assert _rows(mesh.vertices) <= _rows(world)
    for name in ("m.ply", "m.obj", "m.off"):
        mesh.write(tmp_path / name)
        back = tessel.read(tmp_path / name)
        np.testing.assert_array_equal(back.vertices, mesh.vertices)
        np.testing.assert_array_equal(back.faces, mesh.faces)


def test_same_floats_and_offset_as_the_readers(tmp_path):
    rng = np.random.default_rng(5)
    world = UTM + rng.uniform(-300.0, 300.0, size=(5000, 3))
    world[7] = (0.0, 0.0, 0.0)          # a stray point: the scanner's origin
    world[8] = (-1e5, 3.0, 1e15)
    # A binary PLY of doubles, written here, read by the library.
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
              "property double x\nproperty double y\nproperty double z\nend_header\n"
              % len(world)).encode()
    (tmp_path / "w.ply").write_bytes(header + world.astype("<f8").tobytes())
    read = tessel.read(tmp_path / "w.ply")
    mine = tessel.Cloud(world)
    np.testing.assert_array_equal(mine.offset, read.offset)
    assert mine.xyz.tobytes() == read.xyz.tobytes()
    # The bulk is within a float32 step of its local coordinate (3e-5 at
    # 300 units from the offset); world = offset + xyz exactly.
    bulk = np.ones(len(world), bool)
    bulk[[7, 8]] = False
    err = np.abs(mine.points[bulk] - world[bulk])
    assert np.all(err <= np.spacing(np.abs(mine.xyz[bulk])))
    assert err.max() < 3.1e-5
    np.testing.assert_array_equal(mine.points, mine.xyz.astype(np.float64) + mine.offset)


def test_float32_points_are_not_copied():
    pts = fibonacci_sphere(2000).astype(np.float32)
    cloud = tessel.Cloud(pts)
    assert np.shares_memory(cloud.xyz, pts)
    assert not cloud.offset.any()
    # A float32 local frame with an offset given by the caller.
    c2 = tessel.Cloud(pts, offset=UTM)
    assert np.shares_memory(c2.xyz, pts)
    np.testing.assert_array_equal(c2.points, pts.astype(np.float64) + UTM)
    mesh = tessel.reconstruct(c2, method="greedy")
    np.testing.assert_array_equal(mesh.offset, UTM)
    before = pts.copy()
    tessel.reconstruct(pts)
    np.testing.assert_array_equal(pts, before)  # the input is left alone


def test_float64_points_are_converted_once():
    pts = fibonacci_sphere(1000)
    cloud = tessel.Cloud(pts)
    assert cloud.xyz.dtype == np.float32 and not np.shares_memory(cloud.xyz, pts)
    # Non-contiguous and integer input is accepted too.
    wide = np.hstack([pts, np.zeros((1000, 3))])
    np.testing.assert_array_equal(tessel.Cloud(wide[:, :3]).xyz, cloud.xyz)
    ints = (pts * 1000).astype(np.int32)
    np.testing.assert_array_equal(tessel.Cloud(ints).points, ints)


@pytest.mark.parametrize("offset", [1e5, 1e6, 6.4e6])
def test_large_offsets_keep_precision(offset):
    world = fibonacci_sphere(2500, radius=5.0) + offset
    mesh = tessel.reconstruct(world, method="greedy")
    assert np.all(np.abs(mesh.offset - offset) <= 6)
    # Vertices are input points, in input order: match them up.
    v = mesh.vertices
    j = 0
    err = 0.0
    for row in v:
        while np.abs(world[j] - row).max() > 1e-3:
            j += 1
        err = max(err, np.abs(world[j] - row).max())
        j += 1
    # Float32 alone would step 0.008-0.5 units at these magnitudes.
    assert err < 1e-6
    assert tessel.check(mesh)["valid"]
