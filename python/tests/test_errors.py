"""Every error path raises a tessel.Error subclass (or TypeError for a bad
keyword) with the status, the file and the line."""
import numpy as np
import pytest

import tessel
from conftest import fibonacci_sphere

STATUS = {n: v for n, v, _ in tessel._lib._abi.ENUMS["tessel_status"]}


def test_missing_file(tmp_path):
    path = tmp_path / "nope.ply"
    with pytest.raises(tessel.MissingFileError) as e:
        tessel.read(path)
    err = e.value
    assert isinstance(err, FileNotFoundError) and isinstance(err, tessel.InputOutputError)
    assert isinstance(err, tessel.Error)
    assert err.status == STATUS["TESSEL_ERR_IO"] and err.status_name == "TESSEL_ERR_IO"
    assert err.file == str(path)
    assert str(path) in str(err)
    for kind in ("cloud", "mesh"):
        with pytest.raises(FileNotFoundError):
            tessel.read(path, kind=kind)


def test_malformed_text_file_names_the_line(tmp_path):
    path = tmp_path / "bad.xyz"
    path.write_text("0 0 0\n1 0 0\n1 1\n0 1 0\n")
    with pytest.raises(tessel.ParseError) as e:
        tessel.read(path)
    err = e.value
    assert err.status == STATUS["TESSEL_ERR_PARSE"]
    assert err.file.endswith("bad.xyz") and err.line == 3
    assert str(err).startswith(err.file + ": line 3: ")
    assert isinstance(err, ValueError)


def test_truncated_binary_file_names_the_byte(tmp_path, sphere_mesh):
    sphere_mesh.write(tmp_path / "m.ply")
    data = (tmp_path / "m.ply").read_bytes()
    (tmp_path / "cut.ply").write_bytes(data[: len(data) // 2])
    with pytest.raises(tessel.ParseError) as e:
        tessel.read(tmp_path / "cut.ply")
    assert e.value.offset is not None and "byte" in str(e.value)


@pytest.mark.parametrize("shape", [(10,), (10, 2), (10, 4), (2, 5, 4), (10, 3, 1)])
def test_bad_array_shape(shape):
    with pytest.raises(tessel.InvalidArgumentError) as e:
        tessel.reconstruct(np.zeros(shape))
    assert e.value.status == STATUS["TESSEL_ERR_INVALID_ARG"]
    assert isinstance(e.value, ValueError)
    assert "shape" in str(e.value)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_rows(dtype, bad):
    pts = fibonacci_sphere(500).astype(dtype)
    pts[17, 1] = bad
    pts[40, 0] = bad
    with pytest.raises(tessel.InvalidArgumentError) as e:
        tessel.reconstruct(pts)
    msg = str(e.value)
    assert "2 rows are not finite" in msg and "row 17" in msg


def test_coordinates_beyond_the_readers_limit():
    pts = fibonacci_sphere(100)
    pts[3, 2] = 2e15
    with pytest.raises(tessel.InvalidArgumentError, match="row 3"):
        tessel.Cloud(pts)


@pytest.mark.parametrize("arr", [
    np.zeros((10, 3), dtype=np.complex128),
    np.array([["a", "b", "c"]] * 10),
    np.array([[object()] * 3] * 10),
    np.zeros((10, 3), dtype=bool),
])
def test_wrong_dtype(arr):
    with pytest.raises(tessel.InvalidArgumentError, match="dtype"):
        tessel.reconstruct(arr)


def test_bad_normals_and_colors():
    pts = fibonacci_sphere(100)
    with pytest.raises(tessel.InvalidArgumentError, match="rows"):
        tessel.reconstruct(pts, normals=np.zeros((99, 3)))
    bad = pts.copy()
    bad[5] = np.nan
    with pytest.raises(tessel.InvalidArgumentError, match="normals"):
        tessel.Cloud(pts, normals=bad)
    with pytest.raises(tessel.InvalidArgumentError, match=r"\[0, 1\]"):
        tessel.Cloud(pts, colors=np.full((100, 3), 2.0))
    with pytest.raises(tessel.InvalidArgumentError, match="0, 255"):
        tessel.Cloud(pts, colors=np.full((100, 3), 300))


def test_bad_faces():
    v = fibonacci_sphere(10)
    with pytest.raises(tessel.InvalidArgumentError, match="out of range"):
        tessel.Mesh(v, [[0, 1, 10]])
    with pytest.raises(tessel.InvalidArgumentError, match="out of range"):
        tessel.Mesh(v, [[0, -1, 2]])
    with pytest.raises(tessel.InvalidArgumentError, match="integer"):
        tessel.Mesh(v, [[0.0, 1.0, 2.0]])
    with pytest.raises(TypeError):
        tessel.check(v)


def test_bad_keywords(clean_sphere):
    with pytest.raises(TypeError, match="unexpected keyword argument 'muu'.*mu"):
        tessel.reconstruct(clean_sphere, muu=2)
    with pytest.raises(TypeError, match="ambiguous.*front__k"):
        tessel.reconstruct(clean_sphere, method="smooth", k=20)
    with pytest.raises(TypeError, match="must be a number"):
        tessel.reconstruct(clean_sphere, mu="big")
    with pytest.raises(TypeError, match="no effect"):
        tessel.reconstruct(clean_sphere, method="greedy", smooth__front__k=20)
    with pytest.raises(TypeError, match="together"):
        tessel.reconstruct(clean_sphere, mu=2.5, refine__rounds=1)
    with pytest.raises(TypeError, match="method="):
        tessel.reconstruct(clean_sphere, fixed__mode="height")
    with pytest.raises(TypeError, match="cannot be set"):
        tessel.reconstruct(clean_sphere, greedy__existing_count=3)
    with pytest.raises(TypeError, match="no field"):
        tessel.reconstruct(clean_sphere, greedy={"muu": 2})
    with pytest.raises(TypeError, match="unexpected keyword"):
        tessel.normals(clean_sphere, kk=3)
    with pytest.raises(TypeError, match="unexpected keyword"):
        tessel.render(clean_sphere, colour=1)
    with pytest.raises(TypeError, match="unexpected keyword"):
        tessel.write(clean_sphere, "x.ply", binary=1)


def test_values_the_library_refuses(clean_sphere):
    with pytest.raises(tessel.InvalidArgumentError) as e:
        tessel.reconstruct(clean_sphere, mu=100.0)
    assert e.value.status == STATUS["TESSEL_ERR_INVALID_ARG"]
    with pytest.raises(tessel.InvalidArgumentError, match="method must be"):
        tessel.reconstruct(clean_sphere, method="poisson")
    with pytest.raises(tessel.InvalidArgumentError, match="plane must be one of"):
        tessel.reconstruct(clean_sphere, plane="diagonal")
    with pytest.raises(tessel.InvalidArgumentError, match=r"\[0, 4294967295\]"):
        tessel.normals(clean_sphere, k=-1)
    with pytest.raises(tessel.InvalidArgumentError, match="threads"):
        tessel.reconstruct(clean_sphere, threads=-2)
    with pytest.raises(tessel.InvalidArgumentError, match="view must be one of"):
        tessel.render(clean_sphere, view="sideways")


def test_too_few_points():
    with pytest.raises(tessel.TooFewPointsError) as e:
        tessel.reconstruct(np.zeros((2, 3)))
    assert e.value.status == STATUS["TESSEL_ERR_TOO_FEW_POINTS"]
    with pytest.raises(tessel.TooFewPointsError):
        tessel.noise(fibonacci_sphere(10))


def test_range_mode_needs_a_viewpoint(clean_sphere):
    with pytest.raises(tessel.InvalidArgumentError):
        tessel.reconstruct(clean_sphere, method="range")


def test_write_errors(tmp_path, sphere_mesh):
    with pytest.raises(tessel.InputOutputError) as e:
        tessel.write(sphere_mesh, tmp_path / "no" / "such" / "dir.ply")
    assert "dir.ply" in str(e.value)
    with pytest.raises(tessel.InvalidArgumentError):
        tessel.write(sphere_mesh, tmp_path / "mesh.unknown")
    with pytest.raises(tessel.InvalidArgumentError, match="format must be one of"):
        tessel.write(sphere_mesh, tmp_path / "m.ply", format="vrml")
    with pytest.raises(TypeError, match="path"):
        tessel.write(sphere_mesh, 42)
    assert not list(tmp_path.iterdir())  # nothing partial left behind


def test_unsupported(tmp_path, sphere_mesh):
    sphere_mesh.write(tmp_path / "m.ply")
    with pytest.raises(tessel.UnsupportedError):
        tessel.read(tmp_path / "m.ply", bbox=(0, 0, 0, 1, 1, 1))
