"""GGUI's vertex buffers written here and handed to GGUI as they are: meshes, particles and lines declared
without the Python wrapper's per-frame copy of Taichi fields into a buffer of its layout (a kernel compiled for
each field, run over the field's whole capacity every frame).

A vertex is VBO_STRIDE float32 (taichi/ui/staging_buffer.py): position (0-2), normal (3-5; a particle's radius at
3), texture coordinates (6-7), colour RGBA (8-11). The buffers are host memory (:func:`host_buffer`) that lives
as long as the process, as GGUI's own wrapper keeps its vertex buffers: GGUI may hold the address of a buffer past
the frame that drew it, so a buffer freed with its owner could be read or written after it was reused. Buffers
are kept per user and shape, and handed to the next owner of that shape (each frame writes its buffer before GGUI
reads it, so owners that share one never see each other's vertices; users that draw in one frame never share).
"""

import numpy as np
from taichi.ui.utils import get_field_info

__all__ = ["VBO_STRIDE", "host_buffer", "declare_mesh", "declare_particles", "declare_lines"]

VBO_STRIDE = 12  # float32 per vertex of GGUI's vertex buffers: xyz, normal, uv, rgba

_HOST_BUFFERS: dict = {}


def host_buffer(shape: tuple, user: str = "rocks", dtype=np.float32) -> np.ndarray:
    """An array of ``shape`` (float32, or ``dtype``: int32 for indices) that is never freed (see the module
    docstring), one per ``user``; zeroed when first made."""
    key = (user, tuple(shape), np.dtype(dtype).str)
    if key not in _HOST_BUFFERS:
        _HOST_BUFFERS[key] = np.zeros(shape, dtype)
    return _HOST_BUFFERS[key]


def declare_mesh(scene, vbo: np.ndarray, identity: np.ndarray, indices: np.ndarray = None,
                 wireframe: bool = False) -> None:
    """Triangles ``vbo`` (n, VBO_STRIDE; local frame, lit with their normals, per-vertex colours; or the
    vertices of ``indices``, a host buffer of int32 triangle corners) in GGUI ``scene`` as the wrapper's
    ``mesh_instance`` would declare them with one instance (``identity``: a (1, 4, 4) host buffer)."""
    n = len(vbo)
    count = n if indices is None else len(indices)
    scene.scene.mesh_instance(get_field_info(vbo), True, get_field_info(indices), (0.5, 0.5, 0.5), False,
                              get_field_info(identity), 1, 0, count, 0, n, 0, bool(wireframe))


def declare_particles(scene, vbo: np.ndarray) -> None:
    """Particles ``vbo`` (n, VBO_STRIDE: centre, radius, colour) in GGUI ``scene``, as ``scene.particles``
    would with per-vertex colours and radii."""
    scene.scene.particles(get_field_info(vbo), True, True, (0.5, 0.5, 0.5), 0.02, len(vbo), 0)


def declare_lines(scene, vbo: np.ndarray, width: float) -> None:
    """Line segments ``vbo`` (2n, VBO_STRIDE: their ends, colours) ``width`` pixels wide in GGUI ``scene``, as
    ``scene.lines`` would with per-vertex colours."""
    n = len(vbo) - len(vbo) % 2
    scene.scene.lines(get_field_info(vbo), get_field_info(None), True, (0.5, 0.5, 0.5), float(width), n, 0, n, 0)
