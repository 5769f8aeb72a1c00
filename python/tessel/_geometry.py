"""Cloud and Mesh: numpy arrays the library reads in place.

The library stores positions as float32 in a local frame plus a float64
offset per axis (world = offset + xyz), so georeferenced coordinates keep
their precision (docs/formats.md). A Cloud or Mesh holds exactly that:
    xyz      (N, 3) float32, C-contiguous, local coordinates
    offset   (3,) float64
    normals  (N, 3) float32 or None
    colors   (N, 3) uint8 or None
and passes pointers to these arrays to the library: no copy per call.
`points` / `vertices` give world coordinates as a new float64 array.

When arrays are copied on the way in (docs/python.md, "Copies"):
  - float32 C-contiguous (N, 3) points: never (offset 0, or the one given);
  - float64 points: converted once to float32 local coordinates plus the
    offset the file readers would choose (tessel_world_to_local);
  - any other dtype or layout: one conversion;
  - normals float32 and colors uint8 C-contiguous: never; else converted.
Results of the library are wrapped without a copy: their arrays live in the
library's memory until the last numpy array using them is gone.
"""
import ctypes

import numpy as np

from . import _abi, _lib

_F32P = ctypes.POINTER(ctypes.c_float)
_U8P = ctypes.POINTER(ctypes.c_uint8)
_U32P = ctypes.POINTER(ctypes.c_uint32)


# --------------------------------------------------------------------------
# Arrays in
# --------------------------------------------------------------------------

def _bad(msg):
    return _lib.InvalidArgumentError(msg)


def _real_array(a, what):
    arr = np.asarray(a)
    if arr.dtype.kind not in "fiu":
        raise _bad("%s must hold real numbers (a float or integer dtype), got dtype %s"
                   % (what, arr.dtype))
    return arr


def _check_rows(arr, what, n=None):
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise _bad("%s must have shape (N, 3), got %s" % (what, arr.shape))
    if n is not None and arr.shape[0] != n:
        raise _bad("%s has %d rows, the points %d" % (what, arr.shape[0], n))


def _nonfinite_rows(arr, what, limit=None):
    """Raises for rows with a NaN or infinite value (or beyond limit)."""
    ok = np.isfinite(arr).all(axis=1)
    if limit is not None:
        ok &= (np.abs(arr) <= limit).all(axis=1)
    bad = np.flatnonzero(~ok)
    if bad.size:
        raise _bad("%s: %d row%s not finite%s (first: row %d); drop them first, e.g. "
                   "a[np.isfinite(a).all(axis=1)]"
                   % (what, bad.size, "s are" if bad.size > 1 else " is",
                      " or beyond %g" % limit if limit is not None else "", bad[0]))


def _all_finite(arr):
    # A float64 sum of float32 values cannot overflow: it is finite exactly
    # when every value is. One pass, no temporary array.
    return bool(np.isfinite(arr.sum(dtype=np.float64)))


MAX_COORD = 1e15  # readers drop points beyond this (src/io/builder.c)


def local_coords(points, what="points", offset=None):
    """(xyz float32 C-contiguous, offset float64[3]) for (N, 3) points."""
    arr = _real_array(points, what)
    _check_rows(arr, what)
    if offset is not None:
        off = np.array(offset, dtype=np.float64).reshape(-1)
        if off.shape != (3,) or not np.isfinite(off).all():
            raise _bad("offset must be 3 finite numbers, got %r" % (offset,))
        xyz = np.ascontiguousarray(arr, dtype=np.float32)
        if not _all_finite(xyz):
            _nonfinite_rows(xyz, what)
        return xyz, off
    if arr.dtype == np.float32:
        xyz = np.ascontiguousarray(arr)
        if not _all_finite(xyz):
            _nonfinite_rows(xyz, what)
        return xyz, np.zeros(3)
    world = np.ascontiguousarray(arr, dtype=np.float64)
    xyz = np.empty(world.shape, dtype=np.float32)
    off = (ctypes.c_double * 3)()
    n = world.shape[0]
    st = _lib.lib.tessel_world_to_local(world.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                                        n, xyz.ctypes.data_as(_F32P), off)
    if st == _lib.STATUS["TESSEL_ERR_INVALID_ARG"]:
        _nonfinite_rows(world, what, MAX_COORD)
    _lib.check(st, "tessel_world_to_local")
    return xyz, np.array(off[:], dtype=np.float64)


def as_normals(normals, n, what="normals"):
    if normals is None:
        return None
    arr = _real_array(normals, what)
    _check_rows(arr, what, n)
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    if not _all_finite(arr):
        _nonfinite_rows(arr, what)
    return arr


def as_colors(colors, n, what="colors"):
    """uint8 0..255 as is; other integers 0..255; floats 0..1 (Open3D's)."""
    if colors is None:
        return None
    arr = _real_array(colors, what)
    _check_rows(arr, what, n)
    if arr.dtype == np.uint8:
        return np.ascontiguousarray(arr)
    if arr.dtype.kind == "f":
        if arr.size and not (np.isfinite(arr).all() and arr.min() >= 0 and arr.max() <= 1):
            raise _bad("%s: float colours must lie in [0, 1] (uint8 for 0..255)" % what)
        return np.ascontiguousarray(np.rint(arr * 255.0), dtype=np.uint8)
    if arr.size and (arr.min() < 0 or arr.max() > 255):
        raise _bad("%s: integer colours must lie in [0, 255]" % what)
    return np.ascontiguousarray(arr, dtype=np.uint8)


def as_faces(faces, vertex_count, what="faces"):
    arr = np.asarray(faces)
    if arr.dtype.kind not in "iu":
        raise _bad("%s must hold integer vertex indices, got dtype %s" % (what, arr.dtype))
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise _bad("%s must have shape (F, 3), got %s" % (what, arr.shape))
    if arr.size:
        lo, hi = arr.min(), arr.max()
        if lo < 0 or hi >= vertex_count:
            raise _bad("%s: vertex index %d out of range (%d vertices)"
                       % (what, lo if lo < 0 else hi, vertex_count))
    return np.ascontiguousarray(arr, dtype=np.uint32)


def _vec3(v, what):
    a = np.array(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise _bad("%s must be 3 finite numbers, got %r" % (what, v))
    return a


def _ptr(arr, ptype):
    return arr.ctypes.data_as(ptype) if arr is not None else None


# --------------------------------------------------------------------------
# Arrays out: the library's memory, no copy
# --------------------------------------------------------------------------

class _Owner:
    """Frees a cloud or mesh the library allocated once nothing uses it."""

    __slots__ = ("struct", "free")

    def __init__(self, struct, free):
        self.struct = struct
        self.free = free

    def __del__(self):
        try:
            self.free(ctypes.byref(self.struct))
        except Exception:
            pass


class _View:
    __slots__ = ("__array_interface__", "owner")

    def __init__(self, addr, shape, typestr, owner):
        self.__array_interface__ = {"data": (addr, False), "shape": shape,
                                    "typestr": typestr, "version": 3}
        self.owner = owner


def _wrap(ptr, rows, typestr, owner):
    """(rows, 3) array over the library's memory at ptr (rows > 0), keeping
    owner alive."""
    addr = ctypes.cast(ptr, ctypes.c_void_p).value
    return np.asarray(_View(addr, (rows, 3), typestr, owner))


# --------------------------------------------------------------------------
# Cloud
# --------------------------------------------------------------------------

class Cloud:
    """A point cloud: positions, optional normals and colours, optional
    organisation (a scanner's grid) and viewpoint.

    Cloud(points, normals=None, colors=None, *, offset=None, viewpoint=None,
          grid=None)

    points:   (N, 3) array of world coordinates (float64 keeps georeferenced
              coordinates exact: the offset is chosen as the file readers
              do), or float32 local coordinates with `offset`; or (H, W, 3)
              for an organized scan, NaN where the scanner returned nothing
              (the grid is then built and the NaN cells dropped).
    normals:  (N, 3) unit normals (float32 kept as is) or None.
    colors:   (N, 3) uint8 0..255, integers 0..255 or floats 0..1, or None.
    offset:   the world position of local (0, 0, 0) when points are local.
    viewpoint: the scanner's position, world coordinates (orients normals,
              and with a grid makes method="auto" mesh along the rays).
    grid:     (H, W) point index of each cell of an organized scan, -1 (or
              2^32 - 1) where there is none.

    Attributes: xyz (float32 local), offset, normals, colors, grid,
    viewpoint, dropped_nonfinite (points a reader dropped); points (float64
    world, a new array).
    """

    def __init__(self, points, normals=None, colors=None, *, offset=None, viewpoint=None,
                 grid=None):
        if isinstance(points, Cloud):
            src = points
            self._set(src.xyz, src.offset, src.normals if normals is None else
                      as_normals(normals, len(src)),
                      src.colors if colors is None else as_colors(colors, len(src)),
                      src.grid if grid is None else _as_grid(grid, len(src)),
                      src.viewpoint if viewpoint is None else _vec3(viewpoint, "viewpoint"))
            self.dropped_nonfinite = src.dropped_nonfinite
            return
        arr = np.asarray(points) if not isinstance(points, np.ndarray) else points
        if arr.ndim == 3 and grid is None:
            arr, grid, normals, colors = _organized(arr, normals, colors)
        xyz, off = local_coords(arr, "points", offset)
        n = xyz.shape[0]
        self._set(xyz, off, as_normals(normals, n), as_colors(colors, n),
                  _as_grid(grid, n) if grid is not None else None,
                  _vec3(viewpoint, "viewpoint") if viewpoint is not None else None)
        self.dropped_nonfinite = 0

    def _set(self, xyz, offset, normals, colors, grid, viewpoint):
        self.xyz = xyz
        self.offset = offset
        self.normals = normals
        self.colors = colors
        self.grid = grid
        self.viewpoint = viewpoint

    @classmethod
    def _from_c(cls, struct):
        """Wraps a tessel_cloud the library allocated (takes ownership)."""
        self = cls.__new__(cls)
        owner = _Owner(struct, _lib.lib.tessel_cloud_free)
        n = struct.count
        grid = None
        if struct.grid and struct.width and struct.height:
            addr = ctypes.cast(struct.grid, ctypes.c_void_p).value
            grid = np.asarray(_View(addr, (struct.height, struct.width), "<u4", owner))
        self._set(_wrap(struct.xyz, n, "<f4", owner) if n else np.empty((0, 3), np.float32),
                  np.array(struct.offset[:], dtype=np.float64),
                  _wrap(struct.normals, n, "<f4", owner) if struct.normals else None,
                  _wrap(struct.rgb, n, "|u1", owner) if struct.rgb else None,
                  grid,
                  np.array(struct.viewpoint[:]) if struct.has_viewpoint else None)
        self.dropped_nonfinite = int(struct.dropped_nonfinite)
        return self

    def __len__(self):
        return self.xyz.shape[0]

    @property
    def points(self):
        """(N, 3) float64 world coordinates (offset + xyz; a new array)."""
        out = self.xyz.astype(np.float64)
        out += self.offset
        return out

    def __array__(self, dtype=None, copy=None):
        p = self.points  # always a new array
        return p if dtype is None else p.astype(dtype, copy=False)

    def __repr__(self):
        extra = [s for s, a in (("normals", self.normals), ("colors", self.colors),
                                ("grid %dx%d" % (self.grid.shape[1], self.grid.shape[0])
                                 if self.grid is not None else "", self.grid)) if a is not None]
        if self.viewpoint is not None:
            extra.append("viewpoint")
        if self.offset.any():
            extra.append("offset (%s)" % ", ".join("%.17g" % o for o in self.offset))
        return "<tessel.Cloud: %d points%s>" % (len(self), "".join(", " + e for e in extra))

    def _struct(self):
        """A tessel_cloud over this cloud's arrays (valid while self lives)."""
        c = _abi.tessel_cloud()
        c.count = self.xyz.shape[0]
        c.xyz = _ptr(self.xyz, _F32P)
        c.normals = _ptr(self.normals, _F32P)
        c.rgb = _ptr(self.colors, _U8P)
        c.offset[:] = [float(o) for o in self.offset]
        if self.grid is not None:
            c.height, c.width = self.grid.shape
            c.grid = _ptr(self.grid, _U32P)
        if self.viewpoint is not None:
            c.viewpoint[:] = [float(v) for v in self.viewpoint]
            c.has_viewpoint = 1
        return c

    def to_open3d(self):
        """An open3d.geometry.PointCloud (points in world coordinates)."""
        from ._open3d import cloud_to_open3d
        return cloud_to_open3d(self)

    def write(self, path, **params):
        """tessel.write(self, path, **params)."""
        from ._functions import write
        return write(self, path, **params)


def _as_grid(grid, n):
    g = np.asarray(grid)
    if g.ndim != 2 or g.dtype.kind not in "iu":
        raise _bad("grid must be an (H, W) integer array, got %s %s" % (g.dtype, g.shape))
    g64 = g.astype(np.int64)
    g64[g64 < 0] = _lib.NONE_INDEX
    used = g64[g64 != _lib.NONE_INDEX]
    if used.size and used.max() >= n:
        raise _bad("grid: point index %d out of range (%d points)" % (used.max(), n))
    return np.ascontiguousarray(g64, dtype=np.uint32)


def _organized(arr, normals, colors):
    """(H, W, 3) with NaN for missing cells -> points, grid, normals, colors."""
    if arr.shape[2] != 3:
        raise _bad("an organized cloud must have shape (H, W, 3), got %s" % (arr.shape,))
    if arr.dtype.kind not in "fiu":
        raise _bad("points must hold real numbers, got dtype %s" % arr.dtype)
    h, w = arr.shape[:2]
    flat = arr.reshape(h * w, 3)
    ok = np.isfinite(flat).all(axis=1) if arr.dtype.kind == "f" else np.ones(h * w, bool)
    idx = np.cumsum(ok) - 1
    grid = np.where(ok, idx, -1).reshape(h, w)

    def cells(a, what):
        if a is None:
            return None
        a = np.asarray(a)
        if a.shape[:2] != (h, w):
            raise _bad("%s must have shape (%d, %d, 3) like the points, got %s"
                       % (what, h, w, a.shape))
        return a.reshape(h * w, -1)[ok]
    return flat[ok], grid, cells(normals, "normals"), cells(colors, "colors")


# --------------------------------------------------------------------------
# Mesh
# --------------------------------------------------------------------------

class Mesh:
    """A triangle mesh.

    Mesh(vertices, faces, normals=None, colors=None, *, offset=None)

    vertices: (V, 3) world coordinates (float64 kept exact through the
              offset, as in Cloud) or float32 local ones with `offset`.
    faces:    (F, 3) vertex indices, counter-clockwise seen from outside;
              stored as uint32.
    normals, colors: per vertex, as in Cloud.

    Attributes: xyz (float32 local), offset, faces (uint32), normals,
    colors, summary (what tessel.reconstruct did, a dict; None otherwise);
    vertices (float64 world, a new array).
    `vertices, faces = mesh` unpacks it for trimesh, pyvista or meshio:
    trimesh.Trimesh(*mesh), meshio.Mesh(mesh.vertices, [("triangle", mesh.faces)]).
    """

    def __init__(self, vertices, faces, normals=None, colors=None, *, offset=None):
        xyz, off = local_coords(vertices, "vertices", offset)
        n = xyz.shape[0]
        self._set(xyz, off, as_faces(faces, n), as_normals(normals, n), as_colors(colors, n))
        self.summary = None

    def _set(self, xyz, offset, faces, normals, colors):
        self.xyz = xyz
        self.offset = offset
        self.faces = faces
        self.normals = normals
        self.colors = colors

    @classmethod
    def _from_c(cls, struct, summary=None):
        """Wraps a tessel_mesh the library allocated (takes ownership)."""
        self = cls.__new__(cls)
        owner = _Owner(struct, _lib.lib.tessel_mesh_free)
        n, f = struct.vertex_count, struct.triangle_count
        faces = (_wrap(struct.triangles, f, "<u4", owner) if f
                 else np.empty((0, 3), dtype=np.uint32))
        self._set(_wrap(struct.xyz, n, "<f4", owner) if n else np.empty((0, 3), np.float32),
                  np.array(struct.offset[:], dtype=np.float64), faces,
                  _wrap(struct.normals, n, "<f4", owner) if struct.normals and n else None,
                  _wrap(struct.rgb, n, "|u1", owner) if struct.rgb and n else None)
        self.summary = summary
        return self

    @property
    def vertices(self):
        """(V, 3) float64 world coordinates (offset + xyz; a new array)."""
        out = self.xyz.astype(np.float64)
        out += self.offset
        return out

    def __iter__(self):
        yield self.vertices
        yield self.faces

    def __repr__(self):
        extra = [s for s, a in (("normals", self.normals), ("colors", self.colors))
                 if a is not None]
        if self.offset.any():
            extra.append("offset (%s)" % ", ".join("%.17g" % o for o in self.offset))
        return "<tessel.Mesh: %d vertices, %d faces%s>" % (
            self.xyz.shape[0], self.faces.shape[0], "".join(", " + e for e in extra))

    def _struct(self):
        m = _abi.tessel_mesh()
        m.vertex_count = self.xyz.shape[0]
        m.xyz = _ptr(self.xyz, _F32P)
        m.normals = _ptr(self.normals, _F32P)
        m.rgb = _ptr(self.colors, _U8P)
        m.offset[:] = [float(o) for o in self.offset]
        m.triangle_count = self.faces.shape[0]
        m.triangles = _ptr(self.faces, _U32P)
        return m

    def to_open3d(self):
        """An open3d.geometry.TriangleMesh (vertices in world coordinates)."""
        from ._open3d import mesh_to_open3d
        return mesh_to_open3d(self)

    def write(self, path, **params):
        """tessel.write(self, path, **params)."""
        from ._functions import write
        return write(self, path, **params)

    def check(self, **params):
        """tessel.check(self, **params)."""
        from ._functions import check
        return check(self, **params)

    def render(self, path=None, **params):
        """tessel.render(self, path, **params)."""
        from ._functions import render
        return render(self, path, **params)


def as_cloud(points, normals=None, colors=None, what="points"):
    """A Cloud from a Cloud (normals / colors replacing its own when given)
    or from arrays."""
    if isinstance(points, Cloud):
        if normals is None and colors is None:
            return points
        return Cloud(points, normals, colors)
    if isinstance(points, Mesh):
        raise TypeError("%s: a Mesh; pass mesh.vertices for its points" % what)
    return Cloud(points, normals, colors)


def as_mesh(obj, what="mesh"):
    """A Mesh from a Mesh or a (vertices, faces) pair."""
    if isinstance(obj, Mesh):
        return obj
    if isinstance(obj, tuple) and len(obj) == 2:
        return Mesh(obj[0], obj[1])
    raise TypeError("%s must be a tessel.Mesh or a (vertices, faces) pair, got %s"
                    % (what, type(obj).__name__))
