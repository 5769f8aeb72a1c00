"""The functions of the package: one library call each."""
import ctypes
import os
import re

import numpy as np

from . import _abi, _lib, _params, _png
from ._geometry import Cloud, Mesh, _Owner, _wrap, as_cloud, as_mesh

byref = ctypes.byref
lib = _lib.lib
_ENUM = {n: v for items in _abi.ENUMS.values() for n, v, _ in items}

# Which params struct each function takes (tessel.defaults).
STRUCT_OF = {
    "read": "tessel_read_params",
    "write": "tessel_write_params",
    "reconstruct": "tessel_reconstruct_params",
    "smooth": "tessel_smooth_params",
    "simplify": "tessel_simplify_params",
    "normals": "tessel_normals_params",
    "sample": "tessel_sample_params",
    "check": "tessel_check_params",
    "render": "tessel_render_params",
    "stats": "tessel_stats_params",
}


def defaults(function):
    """The library's default parameters of a function, as a nested dict.

    function: "reconstruct", "smooth", "simplify", "normals", "sample",
    "check", "render", "read", "write", "stats", or the function itself
    (tessel.defaults(tessel.reconstruct)). The values come from the
    library's tessel_*_params_default() at each call; the keys are the
    keyword parameters the function takes (nested structs by dict or by
    path: smooth__front__k).
    """
    name = getattr(function, "__name__", function)
    if name not in STRUCT_OF:
        raise ValueError("no parameters for %r; one of %s" % (function, ", ".join(STRUCT_OF)))
    return _params.defaults(STRUCT_OF[name])


def _path(path, what="path"):
    try:
        return os.fsencode(path)
    except TypeError:
        raise TypeError("%s must be a str, bytes or os.PathLike, got %s"
                        % (what, type(path).__name__)) from None


# --------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------

def _ply_face_count(path):
    """Faces a PLY file's header declares (0 without a face element)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except OSError:
        return 0
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return 0
    m = re.search(rb"^element\s+face\s+(\d+)", head[:end], re.M)
    return int(m.group(1)) if m else 0


def read(path, *, kind=None, bbox=None, **params):
    """Reads a point cloud or a mesh file.

    Formats: PLY, XYZ/PTS/TXT/ASC, CSV, OBJ, OFF, PCD, LAS, LAZ/COPC (see the
    README's table); the extension decides, else the content.

    kind: None (default) returns a Mesh when the file has faces (PLY with a
          face element, OBJ, OFF) and a Cloud otherwise; "cloud" or "mesh"
          forces one (a mesh read of a point format has no faces).
    bbox: LAS/LAZ only: keep the points inside (xmin, ymin, zmin, xmax,
          ymax, zmax), world coordinates.
    **params: tessel_read_params fields: format ("auto", "ply", "xyz", ...),
          max_points, max_faces.

    Returns a Cloud or Mesh whose arrays are the library's (no copy).
    Raises MissingFileError (a FileNotFoundError), ParseError with the file
    and the line or byte offset, InputOutputError, UnsupportedError.
    """
    p, _ = _params.build("tessel_read_params", params)
    keep = None
    if bbox is not None:
        keep = np.ascontiguousarray(np.asarray(bbox, dtype=np.float64).reshape(-1))
        if keep.shape != (6,):
            raise _lib.InvalidArgumentError("bbox must be 6 numbers (xmin, ymin, zmin, "
                                            "xmax, ymax, zmax), got %r" % (bbox,))
        p.bbox = keep.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
    bpath = _path(path)
    if kind is None:
        fmt = p.format or lib.tessel_format_from_path(bpath)
        if fmt in (_ENUM["TESSEL_FORMAT_OBJ"], _ENUM["TESSEL_FORMAT_OFF"]):
            kind = "mesh?"
        elif fmt in (_ENUM["TESSEL_FORMAT_PLY"], _ENUM["TESSEL_FORMAT_AUTO"]):
            kind = "mesh" if _ply_face_count(bpath) else "cloud"
        else:
            kind = "cloud"
    elif kind not in ("cloud", "mesh"):
        raise _lib.InvalidArgumentError("kind must be None, 'cloud' or 'mesh', got %r" % (kind,))
    diag = _abi.tessel_diag()
    if kind == "cloud":
        c = _abi.tessel_cloud()
        st = lib.tessel_cloud_read(byref(c), bpath, byref(p), byref(diag))
        _lib.check(st, "read", diag, bpath)
        return Cloud._from_c(c)
    m = _abi.tessel_mesh()
    st = lib.tessel_mesh_read(byref(m), bpath, byref(p), byref(diag))
    _lib.check(st, "read", diag, bpath)
    mesh = Mesh._from_c(m)
    if kind == "mesh?" and mesh.faces.shape[0] == 0:
        cloud = Cloud.__new__(Cloud)
        cloud._set(mesh.xyz, mesh.offset, mesh.normals, mesh.colors, None, None)
        cloud.dropped_nonfinite = 0
        return cloud
    return mesh


def write(obj, path, **params):
    """Writes a Cloud, a Mesh, a (vertices, faces) pair or an (N, 3) array.

    The format comes from the extension (.ply .xyz .pts .txt .csv .obj .off
    .stl) unless format= is given. The file is written whole or not at all
    (a temporary file renamed into place).
    **params: tessel_write_params fields: format, ascii (PLY: 1 writes
    ascii; default binary), write_normals, write_rgb.
    Raises InputOutputError, InvalidArgumentError (unknown extension).
    """
    p, _ = _params.build("tessel_write_params", params)
    bpath = _path(path)
    diag = _abi.tessel_diag()
    if isinstance(obj, (Mesh, tuple)):
        mesh = as_mesh(obj, "obj")
        s = mesh._struct()
        st = lib.tessel_mesh_write(byref(s), bpath, byref(p), byref(diag))
    else:
        cloud = as_cloud(obj, what="obj")
        s = cloud._struct()
        st = lib.tessel_cloud_write(byref(s), bpath, byref(p), byref(diag))
    _lib.check(st, "write", diag, bpath)


# --------------------------------------------------------------------------
# Reconstruction
# --------------------------------------------------------------------------

_METHODS = {
    "auto": ("TESSEL_METHOD_AUTO", None),
    "greedy": ("TESSEL_METHOD_GREEDY", None),
    "smooth": ("TESSEL_METHOD_SMOOTH", None),
    "height": ("TESSEL_METHOD_FIXED_PLANE", "TESSEL_FIXED_PLANE_HEIGHT"),
    "range": ("TESSEL_METHOD_FIXED_PLANE", "TESSEL_FIXED_PLANE_RANGE"),
    "grid": ("TESSEL_METHOD_FIXED_PLANE", "TESSEL_FIXED_PLANE_GRID"),
}
_SCOPE = {"auto": "", "greedy": "greedy", "smooth": "smooth", "height": "fixed",
          "range": "fixed", "grid": "fixed"}


def _summary(s, chosen_by, reason=None):
    d = _params.to_dict(s, "tessel_reconstruct_summary")
    choice = d.pop("choice")
    method = choice["method"]
    if method == "fixed_plane":
        method = choice["mode"]
    measured = bool(choice["measured"])
    out = {
        "method": method,
        "chosen_by": chosen_by,
        "reason": reason or choice["reason"],
        "noise_measured": measured,
        "noise": choice["noise"] if measured else None,
        "noise_ratio": choice["noise_ratio"] if measured else None,
        "choice_seconds": choice["seconds"],
    }
    for k in ("vertices", "triangles", "boundary_edges", "components", "seconds"):
        out[k] = d[k]
    own = {"greedy": "greedy", "smooth": "smooth"}.get(method, "fixed")
    out[own] = d[own]
    if own == "fixed":
        out["denoised"] = bool(d["denoised"])
        if out["denoised"]:
            out["denoise"] = d["denoise"]
    return out


def reconstruct(points, normals=None, colors=None, *, method="auto", threads=None,
                progress=None, **params):
    """Triangulates a point cloud; returns a Mesh.

    points:   (N, 3) array (float64 world coordinates are kept exact
              through the library's offset; float32 C-contiguous arrays are
              read in place, no copy), an organized (H, W, 3) scan with NaN
              holes, or a tessel.Cloud.
    normals:  optional (N, 3) unit normals; colors: optional (N, 3) colours.
    method:   "auto" (default): an organized scan with its viewpoint goes to
              the range mode; otherwise the noise is measured and a clean
              cloud (noise under clean_below surface spacings) goes to
              "greedy", a noisy one to "smooth". A method's own parameters
              choose it (mu=2.5 asks for greedy), as on the command line.
              "greedy": greedy projection, a mesh through the points (Gopi &
              Krishnan 2002). "smooth": the noisy-cloud pipeline, a smooth
              surface near the points (Mederos et al. 2003). "height",
              "range", "grid": a fixed projection plane for terrain, scans
              from one position, organized grids (Gopi & Krishnan, section 5).
    threads:  thread count of every stage (None or 0: OpenMP's default,
              OMP_NUM_THREADS). Results do not depend on it.
    progress: optional callable(stage: str, fraction: float), called on
              this thread a few hundred times per stage. Return True to
              cancel (tessel.CancelledError), or raise: the call is cancelled
              and your exception propagates. Ctrl-C cancels the call too and
              raises KeyboardInterrupt once the library has let go.
    **params: fields of tessel_reconstruct_params, by name when unambiguous
              for the method (mu=2.5, max_hole=0), by path
              (smooth__front__k=20) or by dict (greedy={"mu": 2.5});
              clean_below, denoise. Defaults are the library's
              (tessel.defaults("reconstruct")); unknown names raise
              TypeError.

    The GIL is released while the library works; other Python threads run.

    Returns a Mesh: vertices (V, 3) float64 world, faces (F, 3) uint32,
    normals, colors, and summary, a dict: method (greedy, smooth, height,
    range, grid), chosen_by ("auto", "keywords", "caller"), reason, the
    noise measured for the choice, vertices, triangles, boundary_edges,
    components, seconds (of the library call), and the method's own figures
    under "greedy", "smooth" or "fixed".

    Raises InvalidArgumentError (bad shape, dtype, NaN rows, parameter out
    of range), TooFewPointsError, CancelledError, TypeError (bad keyword).
    """
    if method not in _METHODS:
        raise _lib.InvalidArgumentError("method must be one of %s, got %r"
                                        % (", ".join(repr(m) for m in _METHODS), method))
    cloud = as_cloud(points, normals, colors)
    scope = _SCOPE[method]
    scopes = [("greedy",), ("smooth",)] if method == "auto" else [(scope,)]
    p, resolved = _params.build("tessel_reconstruct_params", params, scopes, threads)
    for path in resolved:
        if path == ("method",) or path == ("fixed", "mode"):
            raise TypeError("give the method as method=%s, not as a parameter"
                            % "|".join(repr(m) for m in _METHODS))
    given = {path[0] for path in resolved if path[0] in ("greedy", "smooth", "fixed")}
    chosen_by, reason = ("auto", None) if method == "auto" else ("caller", None)
    if method == "auto":
        wanted = given & {"greedy", "smooth"}
        if len(wanted) > 1:
            raise TypeError("parameters of greedy projection and of the smooth method "
                            "together: give method='greedy' or method='smooth'")
        if wanted:
            method = wanted.pop()
            chosen_by = "keywords"
            names = sorted("__".join(pth[1:]) for pth in resolved if pth[0] == method)
            reason = "its parameters were given (%s)" % ", ".join(names)
    else:
        other = given - {_SCOPE[method]}
        if other:
            raise TypeError("%s parameters have no effect with method=%r"
                            % (" and ".join(sorted(other)), method))
    enum_method, enum_mode = _METHODS[method]
    p.method = _ENUM[enum_method]
    if enum_mode:
        p.fixed.mode = _ENUM[enum_mode]

    cs = cloud._struct()
    cb = _lib.Callbacks(progress)
    mesh = _abi.tessel_mesh()
    summary = _abi.tessel_reconstruct_summary()
    st = _lib.call(lib.tessel_reconstruct,
                   (byref(cs), byref(p), byref(cb.struct), byref(mesh), byref(summary)), cb)
    result = Mesh._from_c(mesh) if st == 0 else None
    cb.finish(st, "reconstruct")
    result.summary = _summary(summary, chosen_by, reason)
    return result


# --------------------------------------------------------------------------
# Clouds
# --------------------------------------------------------------------------

def smooth(points, normals=None, colors=None, *, threads=None, progress=None, **params):
    """Robust smoothing of a noisy cloud (Mederos et al. 2003, section 2.1).

    Every point moves to the robust projection Q(p) onto the surface fitted
    to its neighbours; the result carries the fitted normals. points,
    normals, colors, threads, progress: as in reconstruct.
    **params: tessel_smooth_params fields (k, sigma_rho, sigma_w, passes,
    quadric, ...; tessel.defaults("smooth")).
    Returns a Cloud (the library's arrays) whose summary is the
    tessel_smooth_stats as a dict.
    """
    cloud = as_cloud(points, normals, colors)
    p, _ = _params.build("tessel_smooth_params", params, threads=threads)
    return _cloud_to_cloud(lib.tessel_smooth, cloud, p, progress, "tessel_smooth_stats",
                           "smooth")


def simplify(points, normals=None, colors=None, *, threads=None, progress=None, **params):
    """Clusters a (smoothed) cloud and keeps one representative per cluster
    (Mederos et al. 2003, sections 2.2-2.3).

    **params: tessel_simplify_params fields: cluster (sigma_max, n_min,
    max_diameter, ...), projection (the operator Q's), keep_unfit; by name
    when unambiguous (max_diameter=6), else by path (cluster__spacing).
    Returns a Cloud with normals; its summary is tessel_simplify_stats.
    """
    cloud = as_cloud(points, normals, colors)
    p, _ = _params.build("tessel_simplify_params", params, threads=threads)
    return _cloud_to_cloud(lib.tessel_simplify, cloud, p, progress, "tessel_simplify_stats",
                           "simplify")


def _cloud_to_cloud(fn, cloud, p, progress, stats_name, what):
    cs = cloud._struct()
    out = _abi.tessel_cloud()
    stats = _abi.STRUCTS[stats_name]()
    cb = _lib.Callbacks(progress)
    st = _lib.call(fn, (byref(cs), byref(out), byref(p), byref(cb.struct), byref(stats)), cb)
    result = Cloud._from_c(out) if st == 0 else None
    cb.finish(st, what)
    result.summary = _params.to_dict(stats, stats_name)
    return result


def normals(points, *, threads=None, progress=None, **params):
    """Estimates unit normals (PCA over the k nearest neighbours, oriented
    by a minimum spanning tree, Hoppe et al. 1992; towards the viewpoint
    of a Cloud that has one).

    **params: tessel_normals_params fields: k (default 16), orient.
    Returns a new (N, 3) float32 array (the library's memory); the input
    is not changed.
    """
    cloud = as_cloud(points)
    p, _ = _params.build("tessel_normals_params", params, threads=threads)
    cs = cloud._struct()
    # The library allocates the normals (it frees and replaces any it is
    # given): a struct of our arrays with none, then the new array alone is
    # handed to an owner that frees it.
    cs.normals = None
    cb = _lib.Callbacks(progress)
    st = _lib.call(lib.tessel_normals_estimate, (byref(cs), byref(p), byref(cb.struct)), cb)
    out = None
    if st == 0:
        only = _abi.tessel_cloud()
        only.count, only.normals = cs.count, cs.normals
        out = _wrap(only.normals, len(cloud), "<f4", _Owner(only, lib.tessel_cloud_free))
    cb.finish(st, "normals")
    return out


def noise(points, *, threads=None):
    """The noise of a cloud, from the cloud alone (docs/noise.md): a dict
    with sigma (world units), surface_spacing, noise_ratio (sigma over the
    surface spacing: under 0.3 is clean for method="auto") and samples.
    TooFewPointsError under 32 points."""
    cloud = as_cloud(points)
    t = _params._scalar(threads or 0, ctypes.c_int, "threads")
    est = _abi.tessel_noise_estimate()
    cs = cloud._struct()
    _lib.check(lib.tessel_cloud_noise(byref(cs), t, byref(est)), "noise")
    return _params.to_dict(est, "tessel_noise_estimate")


def spacing(points):
    """Mean nearest-neighbour spacing of a cloud (world units): the unit of
    every "multiple of the spacing" parameter."""
    cloud = as_cloud(points)
    out = ctypes.c_double()
    cs = cloud._struct()
    _lib.check(lib.tessel_cloud_spacing(byref(cs), byref(out)), "spacing")
    return out.value


def stats(points, *, threads=None, **params):
    """Cloud statistics as tessel info prints them: bbox_min, bbox_max
    (world), diagonal, mean_spacing, median_spacing, exact_duplicates,
    outliers. **params: tessel_stats_params fields."""
    cloud = as_cloud(points)
    p, _ = _params.build("tessel_stats_params", params, threads=threads)
    out = _abi.tessel_cloud_stats()
    cs = cloud._struct()
    _lib.check(lib.tessel_cloud_stats_compute(byref(cs), byref(p), byref(out)), "stats")
    return _params.to_dict(out, "tessel_cloud_stats")


# --------------------------------------------------------------------------
# Meshes
# --------------------------------------------------------------------------

def sample(mesh, count, *, threads=None, progress=None, **params):
    """Draws count points uniformly over a mesh's area (plus optional
    Gaussian noise): the mesh -> points direction, for tests and benchmarks.

    mesh: a Mesh or a (vertices, faces) pair.
    **params: tessel_sample_params fields: noise (world units), noise_rel
    (fraction of the bounding-box diagonal), seed, normals (1: each point
    gets its triangle's normal).
    Returns a Cloud (the library's arrays). The same seed gives the same
    points for any thread count.
    """
    m = as_mesh(mesh)
    if not isinstance(count, (int, np.integer)) or isinstance(count, bool) or count < 0:
        raise TypeError("count must be a non-negative integer, got %r" % (count,))
    p, _ = _params.build("tessel_sample_params", params, threads=threads)
    ms = m._struct()
    out = _abi.tessel_cloud()
    cb = _lib.Callbacks(progress)
    st = _lib.call(lib.tessel_mesh_sample,
                   (byref(ms), int(count), byref(p), byref(cb.struct), byref(out)), cb)
    result = Cloud._from_c(out) if st == 0 else None
    cb.finish(st, "sample")
    return result


_NOT_RUN = (1 << (8 * ctypes.sizeof(ctypes.c_size_t))) - 1  # SIZE_MAX


def check(mesh, *, input=None, reference=None, threads=None, **params):
    """Measures a mesh as tessel check does (docs/check.md); returns a dict.

    mesh:      a Mesh or a (vertices, faces) pair.
    input:     optional cloud the mesh was made from (array or Cloud): adds
               input_as_vertices and the input-to-surface distances.
    reference: optional true surface (Mesh or pair): adds accuracy,
               completeness, chamfer, hausdorff, precision, recall, fscore,
               normal consistency.
    **params:  tessel_check_params fields: self_intersections (default 1),
               tau, samples.

    The dict holds every tessel_mesh_report field (None for
    self-intersection counts when not run, NaN for figures without their
    input) and valid: True for a mesh with a triangle that is manifold,
    consistently oriented, without self-intersections, duplicate or
    degenerate triangles.
    """
    m = as_mesh(mesh)
    p, _ = _params.build("tessel_check_params", params, threads=threads)
    keep = []
    if input is not None:
        ic = as_cloud(input, what="input")
        keep.append(ic._struct())
        p.input = ctypes.pointer(keep[-1])
    if reference is not None:
        rm = as_mesh(reference, "reference")
        keep.append(rm._struct())
        p.reference = ctypes.pointer(keep[-1])
    ms = m._struct()
    report = _abi.tessel_mesh_report()
    _lib.check(lib.tessel_mesh_check(byref(ms), byref(p), byref(report)), "check")
    out = _params.to_dict(report, "tessel_mesh_report")
    for k in ("self_intersections", "self_intersecting_triangles"):
        if out[k] == _NOT_RUN:
            out[k] = None
    out["oriented"] = bool(out["oriented"])
    out["orientable"] = bool(out["orientable"])
    out["valid"] = bool(lib.tessel_mesh_report_valid(byref(report)))
    return out


def render(obj, path=None, *, threads=None, **params):
    """Renders a mesh or a cloud (software rasterizer, orthographic view);
    returns the image as an (H, W, 3) uint8 array and, with path, writes it
    as PNG.

    obj: a Mesh, a (vertices, faces) pair, a Cloud or an (N, 3) array (a
    cloud is drawn as splats). Front faces and back faces get different
    colours, boundary edges are drawn in red: flipped triangles and holes
    show.
    **params: tessel_render_params fields: view ("front", "back", "left",
    "right", "top", "iso", "all"), width, height, z_up, edges, points,
    boundary, point_size, background, front_color, ...
    """
    p, _ = _params.build("tessel_render_params", params, threads=threads)
    if isinstance(obj, (Mesh, tuple)):
        ms = as_mesh(obj, "obj")._struct()
        keep = None
    else:
        keep = as_cloud(obj, what="obj")
        ms = _abi.tessel_mesh()
        cs = keep._struct()
        ms.vertex_count, ms.xyz, ms.normals, ms.rgb = cs.count, cs.xyz, cs.normals, cs.rgb
        ms.offset[:] = cs.offset[:]
    img = np.empty((p.height, p.width, 3), dtype=np.uint8)
    _lib.check(lib.tessel_render(byref(ms), byref(p),
                                 img.ctypes.data_as(ctypes.POINTER(ctypes.c_uint8))), "render")
    del keep
    if path is not None:
        _png.write(path, img)
    return img


# --------------------------------------------------------------------------
# Help: every function's parameters, their defaults and comments, from the
# library itself.
# --------------------------------------------------------------------------

def _add_param_help():
    for name, struct in STRUCT_OF.items():
        fn = globals()[name]
        if name == "reconstruct":
            lines = ["", "Parameters and their defaults (from the library):",
                     "  for every method:"]
            lines += _params.describe(struct, skip=("greedy", "smooth", "fixed", "method"))
            for sub, title in (("greedy", 'method="greedy" (also under "auto")'),
                               ("smooth", 'method="smooth" (also under "auto")'),
                               ("fixed", 'method="height", "range", "grid"')):
                lines.append("  %s: %s__NAME, or NAME alone when unambiguous:" % (title, sub))
                lines += [l for l in _params.describe(_params._field(struct, sub)[2], (),
                                                      indent="    ")
                          if not l.strip().startswith("mode=")]
        else:
            lines = ["", "Parameters and their defaults (from the library):"]
            lines += [l for l in _params.describe(struct) if not l.strip().startswith("bbox")]
        fn.__doc__ = fn.__doc__.rstrip() + "\n" + "\n".join(lines) + "\n"


_add_param_help()
