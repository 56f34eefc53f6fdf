"""Meshes and textures for the game, built with NumPy and handed to Panda3D through its vertex arrays' buffers:
one ``GeomNode`` from vertex positions, colours (and normals) and triangles or lines; flat-shaded convex
hexahedra (the vehicles' body parts of motion/bodies.py), cylinders (wheels), a ribbon along a centre line (the
road), and procedural textures (gravel, packed dirt with wheel ruts).

Colours are RGBA bytes. Flat shading: each face has its own vertices, so its normal is the face's; the lit
vehicles use Panda3D's fixed-function lights (Gouraud over flat faces is flat).
"""

from __future__ import annotations

import numpy as np
from panda3d.core import (Geom, GeomEnums, GeomLines, GeomNode, GeomTriangles, GeomVertexData, GeomVertexFormat,
                          SamplerState, Texture)

from taichi_rocks.motion.bodies import FACE_CORNERS

VERTEX = np.dtype([("p", "<f4", 3), ("c", "u1", 4)])  # GeomVertexFormat.getV3c4(): 16 bytes a vertex
VERTEX_N = np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("c", "u1", 4)])  # getV3n3c4(): 28 bytes


def vertex_view(vdata: GeomVertexData, lit: bool = False) -> np.ndarray:
    """The vertex array of ``vdata`` as a NumPy structured array, written in place (marks it modified)."""
    return np.frombuffer(memoryview(vdata.modifyArray(0)), VERTEX_N if lit else VERTEX)


def vertex_words(vdata: GeomVertexData) -> np.ndarray:
    """The vertex array of ``vdata`` (format V3c4: VERTEX) as (rows, 4) 32-bit words, written in place (marks it
    modified): three float32 words of the position and one word of the colour's four bytes."""
    return np.frombuffer(memoryview(vdata.modifyArray(0)), np.uint32).reshape(-1, 4)


def _geom(name, verts, colors, prim, normals=None, dynamic=False) -> Geom:
    lit = normals is not None
    fmt = GeomVertexFormat.getV3n3c4() if lit else GeomVertexFormat.getV3c4()
    vdata = GeomVertexData(name, fmt, Geom.UHDynamic if dynamic else Geom.UHStatic)
    vdata.setNumRows(len(verts))
    v = vertex_view(vdata, lit)
    v["p"] = verts
    v["c"] = colors
    if lit:
        v["n"] = normals
    geom = Geom(vdata)
    geom.addPrimitive(prim)
    return geom


def _indexed(prim, indices) -> None:
    idx = np.ascontiguousarray(indices, np.uint32).ravel()
    prim.setIndexType(GeomEnums.NT_uint32)
    arr = prim.modifyVertices()
    arr.setNumRows(len(idx))
    np.frombuffer(memoryview(arr), np.uint32)[:] = idx


def triangles(name, verts, colors, tris, normals=None, dynamic=False) -> GeomNode:
    """A GeomNode of triangles ``tris`` (T, 3) over ``verts`` (V, 3), ``colors`` (V, 4) or (4,) bytes, optional
    ``normals`` (V, 3) for lighting; ``dynamic``: its vertices are rewritten while the game runs."""
    prim = GeomTriangles(Geom.UHStatic)
    _indexed(prim, tris)
    node = GeomNode(name)
    node.addGeom(_geom(name, verts, colors, prim, normals, dynamic))
    return node


def lines(name, segments, colors) -> GeomNode:
    """A GeomNode of line segments (S, 2, 3), ``colors`` (S, 4) or (4,) bytes, drawn one pixel wide."""
    seg = np.asarray(segments, np.float32).reshape(-1, 3)
    cols = np.broadcast_to(np.asarray(colors, np.uint8).reshape(-1, 1, 4), (len(seg) // 2, 2, 4)).reshape(-1, 4)
    prim = GeomLines(Geom.UHStatic)
    _indexed(prim, np.arange(len(seg)))
    node = GeomNode(name)
    node.addGeom(_geom(name, seg, cols, prim))
    return node


def rgba(color, alpha: float = 1.0) -> np.ndarray:
    """Bytes of an RGB colour in [0, 1]."""
    c = np.clip(np.append(np.asarray(color, np.float64)[:3], alpha), 0.0, 1.0)
    return np.round(255 * c).astype(np.uint8)


def hexahedron(corners, face_colors) -> tuple:
    """A convex hexahedron (8 corners in motion/bodies.py ``Part.corners`` order) as flat faces: vertices (24, 3),
    normals (24, 3), colours (24, 4), triangles (12, 3) wound counter-clockwise seen from outside (Panda3D's front
    faces). ``face_colors``: (6, 4) bytes, one per face in motion/bodies.py FACES order."""
    c = np.asarray(corners, np.float64)
    centre = c.mean(axis=0)
    verts, normals, cols, tris = [], [], [], []
    for f, idx in enumerate(FACE_CORNERS):
        q = c[list(idx)]
        n = np.cross(q[2] - q[0], q[3] - q[1])
        n /= np.linalg.norm(n)
        if n @ (q.mean(axis=0) - centre) < 0:
            n = -n
        if np.cross(q[1] - q[0], q[2] - q[0]) @ n < 0:  # wind the quad so that n is its front
            q = q[::-1]
        base = len(verts)
        verts += list(q)
        normals += [n] * 4
        cols += [face_colors[f]] * 4
        tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(verts), np.array(normals), np.array(cols, np.uint8), np.array(tris)


def cylinder(radius: float, width: float, sides: int, color, hub_color) -> tuple:
    """A wheel: a cylinder about the y axis, centred at the origin, flat-shaded, with a hub band so that its
    turning shows: vertices, normals, colours, triangles (as :func:`hexahedron`)."""
    a = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    ring = np.stack([radius * np.cos(a), np.zeros(sides), radius * np.sin(a)], 1)
    verts, normals, cols, tris = [], [], [], []
    for k in range(sides):  # the tread, one quad a side
        p0, p1 = ring[k], ring[(k + 1) % sides]
        n = (p0 + p1) / np.linalg.norm(p0 + p1)
        quad = [p0 + (0, -width / 2, 0), p1 + (0, -width / 2, 0), p1 + (0, width / 2, 0), p0 + (0, width / 2, 0)]
        base = len(verts)
        verts += quad
        normals += [n] * 4
        cols += [color] * 4
        tris += [(base, base + 2, base + 1), (base, base + 3, base + 2)]
    for side in (-1.0, 1.0):  # the two faces, a fan each, with a light spoke to see it turn
        centre = len(verts)
        verts.append((0.0, side * width / 2, 0.0))
        normals.append((0.0, side, 0.0))
        cols.append(hub_color)
        for k in range(sides):
            verts.append(0.55 * ring[k] + (0, side * width / 2, 0))
            normals.append((0.0, side, 0.0))
            cols.append(hub_color if k % (sides // 3) == 0 else color)
        for k in range(sides):
            i, j = centre + 1 + k, centre + 1 + (k + 1) % sides
            tris.append((centre, j, i) if side > 0 else (centre, i, j))
    return np.array(verts), np.array(normals), np.array(cols, np.uint8), np.array(tris)


def ribbon(centre, half_width: float, z: float, v_scale: float) -> tuple:
    """A strip along the closed centre line ``centre`` (K, 2): vertices (2K + 2, 3), texture coordinates (u across
    0..1, v along: distance / ``v_scale``) and triangles."""
    c = np.vstack([centre, centre[:1]])
    d = np.gradient(c, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    left = np.stack([-d[:, 1], d[:, 0]], 1)
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    verts = np.empty((2 * len(c), 3))
    verts[0::2, :2], verts[1::2, :2] = c - half_width * left, c + half_width * left
    verts[:, 2] = z
    uv = np.empty((2 * len(c), 2))
    uv[0::2, 0], uv[1::2, 0] = 0.0, 1.0
    uv[:, 1] = np.repeat(along / v_scale, 2)
    k = np.arange(len(c) - 1)
    tris = np.concatenate([np.stack([2 * k, 2 * k + 2, 2 * k + 1], 1), np.stack([2 * k + 1, 2 * k + 2, 2 * k + 3], 1)])
    return verts, uv, tris


def grid(lo, hi, cell: float) -> tuple:
    """A flat grid over the rectangle ``lo`` .. ``hi`` (x, y) at z = 0 in squares of about ``cell``: vertices (V, 3)
    and triangles facing +z."""
    nx, ny = (max(int(np.ceil((hi[i] - lo[i]) / cell)), 1) for i in (0, 1))
    x, y = np.linspace(lo[0], hi[0], nx + 1), np.linspace(lo[1], hi[1], ny + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    verts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    a = (i * (ny + 1) + j).ravel()
    b, c, d = a + (ny + 1), a + (ny + 1) + 1, a + 1
    return verts, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def textured(name, verts, uv, tris) -> GeomNode:
    """A GeomNode of textured triangles (white vertices, texture coordinates ``uv``)."""
    fmt = GeomVertexFormat.getV3t2()
    vdata = GeomVertexData(name, fmt, Geom.UHStatic)
    vdata.setNumRows(len(verts))
    v = np.frombuffer(memoryview(vdata.modifyArray(0)), np.dtype([("p", "<f4", 3), ("t", "<f4", 2)]))
    v["p"], v["t"] = verts, uv
    prim = GeomTriangles(Geom.UHStatic)
    _indexed(prim, tris)
    geom = Geom(vdata)
    geom.addPrimitive(prim)
    node = GeomNode(name)
    node.addGeom(geom)
    return node


def texture(name, rgb: np.ndarray) -> Texture:
    """A mipmapped, repeating texture from an (H, W, 3) float image in [0, 1] (row 0 at the top)."""
    return _texture(name, rgb, Texture.F_rgb, [2, 1, 0], SamplerState.FT_linear_mipmap_linear,
                    SamplerState.WM_repeat)


def texture_rgba(name, rgba_image: np.ndarray) -> Texture:
    """A clamped texture with alpha from an (H, W, 4) float image in [0, 1] (row 0 at the top). The
    software renderer blends by a texture's alpha (it ignores the alpha of vertex colours)."""
    return _texture(name, rgba_image, Texture.F_rgba, [2, 1, 0, 3], SamplerState.FT_linear, SamplerState.WM_clamp)


def _texture(name, image: np.ndarray, fmt, channels: list, min_filter, wrap) -> Texture:
    """A texture of 8-bit channels from a float image in [0, 1]: Panda3D wants BGR(A), the bottom row first."""
    h, w, _ = image.shape
    tex = Texture(name)
    tex.setup2dTexture(w, h, Texture.T_unsigned_byte, fmt)
    tex.setRamImage(np.round(255 * np.clip(image[::-1][..., channels], 0, 1)).astype(np.uint8).tobytes())
    tex.setMinfilter(min_filter)
    tex.setMagfilter(SamplerState.FT_linear)
    tex.setWrapU(wrap)
    tex.setWrapV(wrap)
    return tex


def card(name, x0, x1, y0, y1, plane: str = "xy") -> GeomNode:
    """A textured rectangle, u along its first axis: in the xy plane facing +z, or the xz plane facing -y (what
    Panda3D's billboards turn to the camera)."""
    if plane == "xy":
        verts = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    else:
        verts = np.array([[x0, 0.0, y0], [x1, 0.0, y0], [x1, 0.0, y1], [x0, 0.0, y1]])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    return textured(name, verts, uv, np.array([[0, 1, 2], [0, 2, 3]]))


def _noise(rng, size: int, scales) -> np.ndarray:
    """Tileable value noise in [0, 1] from a sum of octaves (``scales``: cells per side, weight)."""
    out = np.zeros((size, size))
    for cells, weight in scales:
        grid = rng.random((cells, cells))
        x = np.arange(size) * cells / size
        i0 = np.floor(x).astype(int)
        f = x - i0
        f = f * f * (3 - 2 * f)
        i1 = (i0 + 1) % cells
        rows = grid[i0][:, i0] * (1 - f)[None, :] + grid[i0][:, i1] * f[None, :]
        rows1 = grid[i1][:, i0] * (1 - f)[None, :] + grid[i1][:, i1] * f[None, :]
        out += weight * (rows * (1 - f)[:, None] + rows1 * f[:, None])
    return out / sum(w for _, w in scales)


def gravel_texture(seed: int = 1, size: int = 128) -> np.ndarray:
    """Loose gravel seen from afar: grey-brown speckle over a low-frequency mottle, (size, size, 3)."""
    rng = np.random.default_rng(seed)
    mottle = _noise(rng, size, ((4, 1.0), (8, 0.5)))
    speck = rng.random((size, size))
    base = np.array([0.47, 0.43, 0.38])
    shade = 0.78 + 0.22 * mottle[..., None] + 0.16 * (speck[..., None] - 0.5)
    return base * shade


def road_texture(seed: int = 2, size: int = 128, ruts=(0.36, 0.64)) -> np.ndarray:
    """Packed dirt across a road (u: across, 0..1) with two darker wheel ruts at ``ruts`` and softer edges."""
    rng = np.random.default_rng(seed)
    u = (np.arange(size) + 0.5) / size
    rut = sum(np.exp(-((u - r) / 0.06) ** 2) for r in ruts)
    edge = np.clip(np.minimum(u, 1 - u) / 0.08, 0, 1)
    grain = _noise(rng, size, ((8, 1.0), (32, 0.6))) + 0.3 * (rng.random((size, size)) - 0.5)
    base = np.array([0.44, 0.39, 0.33])
    shade = (0.92 - 0.18 * rut[None, :] + 0.12 * (grain - 0.5)) * (0.85 + 0.15 * edge[None, :])
    return base * shade[..., None]
