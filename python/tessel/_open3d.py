"""Conversions to and from Open3D (imported only when asked for)."""
import numpy as np

from ._geometry import Cloud, Mesh


def _o3d():
    try:
        import open3d
    except ImportError as e:
        raise ImportError("open3d is not installed (Debian: apt-get install python3-open3d)") \
            from e
    return open3d


def cloud_to_open3d(cloud):
    o3d = _o3d()
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cloud.points))
    if cloud.normals is not None:
        pcd.normals = o3d.utility.Vector3dVector(cloud.normals.astype(np.float64))
    if cloud.colors is not None:
        pcd.colors = o3d.utility.Vector3dVector(cloud.colors / 255.0)
    return pcd


def mesh_to_open3d(mesh):
    o3d = _o3d()
    out = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices),
                                    o3d.utility.Vector3iVector(mesh.faces.astype(np.int32)))
    if mesh.normals is not None:
        out.vertex_normals = o3d.utility.Vector3dVector(mesh.normals.astype(np.float64))
    if mesh.colors is not None:
        out.vertex_colors = o3d.utility.Vector3dVector(mesh.colors / 255.0)
    return out


def from_open3d(obj):
    """A Cloud from an open3d.geometry.PointCloud, a Mesh from an
    open3d.geometry.TriangleMesh (normals and colours when it has them;
    coordinates are float64, kept exact through the offset).
    """
    o3d = _o3d()
    if isinstance(obj, o3d.geometry.PointCloud):
        return Cloud(np.asarray(obj.points),
                     np.asarray(obj.normals) if obj.has_normals() else None,
                     np.clip(np.asarray(obj.colors), 0.0, 1.0) if obj.has_colors() else None)
    if isinstance(obj, o3d.geometry.TriangleMesh):
        return Mesh(np.asarray(obj.vertices), np.asarray(obj.triangles),
                    np.asarray(obj.vertex_normals) if obj.has_vertex_normals() else None,
                    np.clip(np.asarray(obj.vertex_colors), 0.0, 1.0)
                    if obj.has_vertex_colors() else None)
    raise TypeError("from_open3d takes an open3d.geometry.PointCloud or TriangleMesh, got %s"
                    % type(obj).__name__)
