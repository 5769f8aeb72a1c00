"""The other functions, the methods, parameters and help."""
import pydoc
import struct
import zlib

import numpy as np
import pytest

import tessel
from conftest import fibonacci_sphere, organized_scan, sphere, terrain


def test_smooth_and_simplify():
    pts = sphere(6000, noise=0.01, seed=2)
    sm = tessel.smooth(pts)
    assert isinstance(sm, tessel.Cloud) and len(sm) == len(pts)
    assert sm.normals is not None and sm.normals.shape == (len(pts), 3)
    r_in = np.linalg.norm(pts, axis=1)
    r_out = np.linalg.norm(sm.points, axis=1)
    assert np.std(r_out - 1) < 0.5 * np.std(r_in - 1)  # less noise
    assert sm.summary["spacing"] > 0 and sm.summary["rms_displacement"] > 0
    reps = tessel.simplify(sm, max_diameter=6)
    assert 0 < len(reps) < len(sm) and reps.normals is not None
    assert reps.summary["representatives"] == len(reps)
    with pytest.raises(TypeError, match="ambiguous.*cluster__spacing"):
        tessel.simplify(sm, spacing=0.1)


def test_normals_are_unit_and_outward():
    pts = fibonacci_sphere(3000)
    n = tessel.normals(pts, k=12)
    assert n.shape == pts.shape and n.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    assert np.mean(np.einsum("ij,ij->i", n, pts) > 0.9) > 0.99
    # A given cloud's own normals are not touched.
    c = tessel.Cloud(pts, normals=-pts)
    before = c.normals.copy()
    tessel.normals(c)
    np.testing.assert_array_equal(c.normals, before)
    # Towards a viewpoint: every normal faces it.
    inside = tessel.normals(tessel.Cloud(pts, viewpoint=(0, 0, 0)))
    assert np.all(np.einsum("ij,ij->i", inside, pts) < 0)


def test_sample(sphere_mesh):
    c = tessel.sample(sphere_mesh, 5000, seed=7)
    assert len(c) == 5000 and c.normals is not None
    r = np.linalg.norm(c.points, axis=1)
    assert r.max() <= 1.0 + 1e-6 and r.min() > 0.99
    again = tessel.sample(sphere_mesh, 5000, seed=7, threads=1)
    np.testing.assert_array_equal(again.xyz, c.xyz)
    noisy = tessel.sample(sphere_mesh, 2000, noise_rel=0.01, normals=0)
    assert noisy.normals is None
    assert np.std(np.linalg.norm(noisy.points, axis=1)) > 0.005


def test_check_against_a_reference(sphere_mesh):
    fine = tessel.reconstruct(fibonacci_sphere(8000))
    r = tessel.check(sphere_mesh, reference=fine, input=fibonacci_sphere(4000), samples=20000)
    assert r["valid"] and r["fscore"] > 99 and r["chamfer"] < 0.01
    assert 0.99 < r["normal_consistency"] <= 1.0
    assert tessel.check(sphere_mesh, self_intersections=0)["self_intersections"] is None
    assert sphere_mesh.check()["valid"]


def test_render(tmp_path, sphere_mesh):
    img = tessel.render(sphere_mesh, width=320, height=200, view="iso")
    assert img.shape == (200, 320, 3) and img.dtype == np.uint8
    bg = tessel.defaults("render")["background"]
    assert (img != np.array(bg, np.uint8)).any(axis=2).mean() > 0.1  # something drawn
    path = tmp_path / "mesh.png"
    out = sphere_mesh.render(path, width=320, height=200, view="iso")
    np.testing.assert_array_equal(out, img)
    assert _decode_png(path.read_bytes()).tobytes() == img.tobytes()
    d = tessel.defaults("render")
    full = tessel.render(fibonacci_sphere(2000))  # a cloud: splats, default size
    assert full.shape == (d["height"], d["width"], 3)
    sheet = tessel.render((sphere_mesh.vertices, sphere_mesh.faces), view="all", width=200,
                          height=200, background=(0, 0, 0))
    assert tuple(sheet[0, 0]) == (0, 0, 0)


def _decode_png(data):
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w, h = 8, b"", None, None
    while pos < len(data):
        n = struct.unpack(">I", data[pos:pos + 4])[0]
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        assert zlib.crc32(kind + body) == struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0]
        if kind == b"IHDR":
            w, h = struct.unpack(">II", body[:8])
            assert body[8:10] == b"\x08\x02"
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    assert (raw[:, 0] == 0).all()
    return raw[:, 1:].reshape(h, w, 3)


def test_noise_spacing_stats():
    clean = tessel.noise(fibonacci_sphere(5000))
    noisy = tessel.noise(sphere(5000, noise=0.02))
    assert clean["noise_ratio"] < 0.3 < noisy["noise_ratio"]
    assert set(clean) == {"sigma", "surface_spacing", "noise_ratio", "samples"}
    h = tessel.spacing(fibonacci_sphere(5000))
    assert 0.01 < h < 0.05
    s = tessel.stats(fibonacci_sphere(5000) + 1e6)
    assert s["bbox_min"][0] == pytest.approx(1e6 - 1, abs=1e-3)
    assert s["mean_spacing"] == pytest.approx(h, rel=1e-6)


def test_auto_chooses_smooth_for_noise():
    mesh = tessel.reconstruct(sphere(8000, noise=0.02, seed=4))
    s = mesh.summary
    assert s["method"] == "smooth" and s["chosen_by"] == "auto" and "noisy" in s["reason"]
    assert s["noise_ratio"] >= 0.3 and "smooth" in s and "greedy" not in s
    assert tessel.check(mesh)["valid"]


def test_keywords_choose_the_method():
    mesh = tessel.reconstruct(sphere(4000, noise=0.02, seed=4), mu=2.5)
    assert mesh.summary["method"] == "greedy" and mesh.summary["chosen_by"] == "keywords"
    assert "mu" in mesh.summary["reason"]


def test_setting_a_field_sets_its_switch():
    """mu=... turns mu_from_sampling off, viewpoint=... turns use_viewpoint
    on, as the command line's --mu and --viewpoint do; unless given."""
    pts = sphere(4000, seed=4)
    auto_mu = tessel.reconstruct(pts, method="greedy").summary["greedy"]["mu"]
    assert tessel.reconstruct(pts, mu=2.5).summary["greedy"]["mu"] == 2.5
    kept = tessel.reconstruct(pts, mu=2.5, mu_from_sampling=1).summary["greedy"]["mu"]
    assert kept == auto_mu
    p, _ = tessel._params.build("tessel_reconstruct_params", {"viewpoint": (1, 2, 3)},
                                [("fixed",)])
    assert p.fixed.use_viewpoint == 1 and list(p.fixed.viewpoint) == [1, 2, 3]
    p, _ = tessel._params.build("tessel_reconstruct_params", {"max_diameter": 5},
                                [("smooth",)])
    assert p.smooth.auto_cluster_size == 0 and p.smooth.simplify.cluster.max_diameter == 5
    mesh = tessel.reconstruct(fibonacci_sphere(4000), front__k=20, refine={"rounds": 0})
    assert mesh.summary["method"] == "smooth"
    assert tessel.check(mesh)["valid"]


def test_height_mode():
    mesh = tessel.reconstruct(terrain(), method="height", points_per_dexel=1)
    s = mesh.summary
    assert s["method"] == "height" and s["chosen_by"] == "caller" and "fixed" in s
    r = tessel.check(mesh)
    assert r["valid"] and r["components"] == 1
    up = np.cross(mesh.vertices[mesh.faces[:, 1]] - mesh.vertices[mesh.faces[:, 0]],
                  mesh.vertices[mesh.faces[:, 2]] - mesh.vertices[mesh.faces[:, 0]])[:, 2]
    assert (up > 0).all()


def test_organized_scan_goes_to_the_range_mode():
    scan = organized_scan()
    cloud = tessel.Cloud(scan, viewpoint=(0, 0, 0))
    assert cloud.grid.shape == (60, 80) and len(cloud) == 60 * 80 - 16
    assert (cloud.grid == 2 ** 32 - 1).sum() == 16
    mesh = tessel.reconstruct(cloud)
    s = mesh.summary
    assert s["method"] == "range" and s["chosen_by"] == "auto" and "organized" in s["reason"]
    assert tessel.check(mesh)["valid"]
    # The grid mode on the same scan; the range mode on a plain cloud with a
    # viewpoint given as a parameter.
    assert tessel.check(tessel.reconstruct(cloud, method="grid"))["valid"]
    pts = cloud.points
    m2 = tessel.reconstruct(pts, method="range", viewpoint=(0, 0, 0))
    assert m2.summary["method"] == "range" and len(m2.faces) > 0
    # Without a viewpoint a grid alone is not enough for auto.
    assert tessel.reconstruct(tessel.Cloud(scan)).summary["method"] != "range"


def test_colors_survive(tmp_path):
    pts = fibonacci_sphere(3000).astype(np.float32)
    colors = (np.abs(pts) * 255).astype(np.uint8)
    mesh = tessel.reconstruct(pts, colors=colors / 255.0, method="greedy")
    assert mesh.colors is not None and mesh.colors.dtype == np.uint8
    idx = {r.tobytes(): i for i, r in enumerate(pts.astype(np.float64))}
    rows = [idx[r.tobytes()] for r in mesh.vertices]
    np.testing.assert_array_equal(mesh.colors, colors[rows])


def test_defaults_come_from_the_library():
    d = tessel.defaults("reconstruct")
    assert d["method"] == "auto" and d["clean_below"] == pytest.approx(0.3)
    p = tessel._lib.lib.tessel_greedy_params_default()
    assert d["greedy"]["mu"] == p.mu and d["greedy"]["max_hole"] == p.max_hole
    assert d["fixed"]["mode"] == "range"
    assert tessel.defaults(tessel.normals)["k"] == tessel._lib.lib.tessel_normals_params_default().k
    with pytest.raises(ValueError):
        tessel.defaults("nothing")


def test_help_reads_well():
    text = pydoc.render_doc(tessel.reconstruct, renderer=pydoc.plaintext)
    for needle in ("points:", "method:", "progress:", "Returns a Mesh", "mu=2", "front__k=16",
                   "clean_below=0.3", "Raises"):
        assert needle in text, needle
    for name in tessel.__all__:
        obj = getattr(tessel, name)
        assert obj.__doc__ and len(obj.__doc__) > 40, name
    assert "existing" not in text  # pointer fields are not parameters


def test_repr():
    c = tessel.Cloud(fibonacci_sphere(10) + 1e6)
    assert repr(c).startswith("<tessel.Cloud: 10 points, offset (")
    assert "faces" in repr(tessel.reconstruct(fibonacci_sphere(500)))
    np.testing.assert_array_equal(np.asarray(c), c.points)
