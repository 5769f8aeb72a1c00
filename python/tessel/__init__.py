"""tessel: point clouds to triangle meshes, numpy in, numpy out.

    import numpy as np, tessel
    mesh = tessel.reconstruct(points)            # (N, 3) array -> Mesh
    mesh.vertices, mesh.faces                    # (V, 3) float64, (F, 3) uint32
    mesh.summary["method"], mesh.summary["reason"]
    tessel.check(mesh)["valid"]                  # manifold, oriented, no self-intersection
    tessel.write(mesh, "out.ply"); tessel.read("scan.las")
    tessel.render(mesh, "mesh.png", view="all")

A ctypes binding of libtessel (no compiler needed): the library reads the
arrays in place, runs with the GIL released, reports progress to a Python
callable and stops on Ctrl-C. Parameters are the C params structs' fields
with the library's defaults (tessel.defaults("reconstruct")). Errors are
tessel.Error subclasses carrying the status, file and line.

Functions: read, write, reconstruct, smooth, simplify, normals, sample,
check, render, noise, spacing, stats, defaults, from_open3d.
Classes: Cloud, Mesh. See docs/python.md.
"""
from ._lib import (CancelledError, Error, InputOutputError, InternalError,
                   InvalidArgumentError, LimitError, MissingFileError, OutOfMemoryError,
                   ParseError, TooFewPointsError, UnsupportedError, VERSION as __version__,
                   LIBRARY_PATH as library_path)
from ._geometry import Cloud, Mesh
from ._functions import (check, defaults, noise, normals, read, reconstruct, render, sample,
                         simplify, smooth, spacing, stats, write)
from ._open3d import from_open3d

__all__ = [
    "Cloud", "Mesh", "read", "write", "reconstruct", "smooth", "simplify", "normals",
    "sample", "check", "render", "noise", "spacing", "stats", "defaults", "from_open3d",
    "Error", "InvalidArgumentError", "OutOfMemoryError", "InputOutputError",
    "MissingFileError", "ParseError", "UnsupportedError", "LimitError",
    "TooFewPointsError", "CancelledError", "InternalError",
]
