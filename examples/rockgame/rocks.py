"""The rocks as the game draws them: a mirror of the bed kept from ``Simulation.changes()`` alone, and Panda3D
meshes of a small pebble per rock, whose vertices are written in place for the rows that changed and no others.

Mirror: positions (N, 3) float64 world m, phase (N,) and orientations (N, 4) quaternions (x, y, z, w), by rock id;
each frame ``apply(rows)`` sets ``mirror[ids] = rows`` (the first call of ``changes()`` gives every rock). The
radii come once, at the start, from ``state()`` (changes() does not carry them: a rock's radius never changes).

Pebble: rock i is a tetrahedron (4 vertices, 4 triangles), one of SHAPES irregular templates t_s (flattened, as
gravel is), scaled to its radius r and turned by its orientation q:

    vertex_k = c + R(q) (r SIZE t_s,k) - origin,      R(q) the rotation of the unit quaternion q

(c its centre, ``origin`` the render origin: the meshes are float32). Its vertex colours are lit when the row
changes, by a sun fixed in the world: colour_k = base_i (AMBIENT + DIFFUSE max(0, n_k . sun)), n_k = R(q) t_s,k /
|t_s,k| (a pebble's normal at a corner is about the direction from its centre).

Chunks: Panda3D's software renderer transforms every vertex of a mesh it draws (~0.1 us each here: 50,000
pebbles, 200,000 vertices, cost 14-25 ms a frame), so the rocks live in chunks, one per CELL x CELL m cell of a
grid fixed in the world, each with its own vertex buffers holding the rocks in its cell packed from slot 0. The
engine culls the chunks out of view, and draws each chunk of resting rocks as pebbles within GROUND_LOD of the
camera and as one-pixel points beyond (Panda3D's LODNode; a 3 cm stone 10 m away is ~3 pixels across at 960x540,
and the pebbles cost 4 vertices a rock against the point's 1: measured, 13 ms a frame against 40 with every rock a
pebble). The stones in flight share one chunk of their own, always pebbles and never culled: they are what the
game is about, few (a few hundred) and on the move (a chunk per cell would see them change cells every frame).
A changed row is written where its rock is; a rock that moved to another chunk leaves its slot (the chunk's last
rock moves into the hole: one copy of its vertices) and is appended to its new chunk. A chunk emptied (the bed
moved on) is used again for a cell the bed reaches.

Streaks: each stone in flight is also drawn as a one-pixel line from where it was at the previous frame, as the
camera saw it, to where it is (the rows that changed carry both: the mirror before and after; the camera rides
with the player, so the stone's place a frame ago is moved on by the player's move in the frame): the blur of a
1/60 s exposure on a camera moving with the car, which is what makes a 3 cm stone readable at 10 m.
"""

from __future__ import annotations

import numpy as np
from panda3d.core import (BoundingBox, Geom, GeomEnums, GeomLines, GeomNode, GeomPoints, GeomTriangles,
                          GeomVertexData, GeomVertexFormat, LODNode, NodePath, OmniBoundingVolume, Point3)

from .meshes import vertex_view, vertex_words

SHAPES = 16  # irregular templates, chosen by rock id
SIZE = 1.25  # a template's corners lie this many radii from the centre (a tetrahedron shows less than its sphere)
AMBIENT, DIFFUSE = 0.55, 0.6
SUN = np.array([-0.45, 0.35, 0.82]) / np.linalg.norm([-0.45, 0.35, 0.82])  # towards the sun, world frame
TETRA = np.array([[0.0, 0.0, 1.0], [0.943, 0.0, -0.333], [-0.471, 0.816, -0.333], [-0.471, -0.816, -0.333]])
FACES = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])  # counter-clockwise seen from outside
CELL = 6.0  # m: a chunk's cell
GROUND_LOD = 10.0  # m from the camera to a chunk's centre: pebbles nearer, points farther
AIR = 1  # the key of the stones in flight's chunk (a cell's key is even)
FIRST_CAPACITY = 4096  # rocks a new chunk holds before it grows (the bed's gravel: ~2,600 in a cell)
FLYING = 1  # the phase code of a stone in the air (docs/records.md)
REACH = (0.2, -0.5, 12.0)  # m: a chunk's bounds beyond its cell (its pebbles' corners), below and above ground


def templates(seed: int = 11) -> np.ndarray:
    """(SHAPES, 4, 3): tetrahedra stretched along random axes and flattened (gravel is flatter than round)."""
    rng = np.random.default_rng(seed)
    out = np.empty((SHAPES, 4, 3))
    for s in range(SHAPES):
        a = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        a[:, 0] *= np.sign(np.linalg.det(a))  # a rotation, not a reflection: the faces keep their winding
        t = TETRA @ a.T @ np.diag(rng.uniform(0.8, 1.2, 3))
        t[:, 2] *= 0.55  # gravel lies flat: a low mound, not a spike
        out[s] = t + rng.normal(scale=0.06, size=(4, 3))
    return out


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v (k, m, 3) turned by unit quaternions q (k, 4) as (x, y, z, w): v R(q)^T, R(q) the rotation matrix
    [[1 - 2(y^2 + z^2), 2(xy - zw), 2(xz + yw)], [2(xy + zw), 1 - 2(x^2 + z^2), 2(yz - xw)],
     [2(xz - yw), 2(yz + xw), 1 - 2(x^2 + y^2)]] (one batched product: cheaper than cross products here)."""
    x, y, z, w = (np.asarray(q, np.float64)[:, i] for i in range(4))
    m = np.empty((len(x), 3, 3))
    m[:, 0, 0], m[:, 0, 1], m[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    m[:, 1, 0], m[:, 1, 1], m[:, 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    m[:, 2, 0], m[:, 2, 1], m[:, 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    return np.matmul(v, m.transpose(0, 2, 1))


def rock_colours(ids: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(N, 3) base colours in [0, 1]: grey to brown gravel, by a hash of the id; the big stones a little lighter."""
    h = (ids.astype(np.uint64) * np.uint64(2654435761)) % np.uint64(2 ** 32)
    a = (h % np.uint64(1024)).astype(np.float64) / 1024.0
    b = ((h >> np.uint64(10)) % np.uint64(1024)).astype(np.float64) / 1024.0
    grey = np.array([0.56, 0.55, 0.53])
    brown = np.array([0.60, 0.49, 0.37])
    c = grey + a[:, None] * (brown - grey)
    lo, hi = radii.min(), max(radii.max(), radii.min() + 1e-9)
    return c * (0.72 + 0.3 * b[:, None] + 0.12 * ((radii - lo) / (hi - lo))[:, None])


class Chunk:
    """One cell's rocks (module docstring): ``count`` rocks in slots 0 .. count - 1 of a pebble buffer (4 vertices
    a rock) and a point buffer (1), drawn through an LODNode under ``parent``."""

    def __init__(self, parent: NodePath, capacity: int = FIRST_CAPACITY):
        self.capacity, self.count, self.key = 0, 0, None
        self.rock = np.empty(0, np.int64)
        self.mesh = GeomVertexData("pebbles", GeomVertexFormat.getV3c4(), Geom.UHDynamic)
        self.points = GeomVertexData("points", GeomVertexFormat.getV3c4(), Geom.UHDynamic)
        self.tris = GeomTriangles(Geom.UHDynamic)
        self.tris.setIndexType(GeomEnums.NT_uint32)
        self.dots = GeomPoints(Geom.UHDynamic)
        self.lod = LODNode("chunk")
        self.node = parent.attachNewNode(self.lod)
        self.lod.setFinal(True)  # its bounds are its cell's (place): never computed from the vertices written
        for vdata, prim in ((self.mesh, self.tris), (self.points, self.dots)):
            geom = Geom(vdata)
            geom.addPrimitive(prim)
            gn = GeomNode("rocks")
            gn.addGeom(geom)
            self.node.attachNewNode(gn)
        self._grow(capacity)

    def _grow(self, capacity: int) -> None:
        self.mesh.setNumRows(4 * capacity)
        self.points.setNumRows(capacity)
        idx = self.tris.modifyVertices()  # the pattern for every slot; _sized says how much of it to draw
        idx.setNumRows(12 * capacity)
        a = np.frombuffer(memoryview(idx), np.uint32).reshape(-1, 4, 3)
        a[:] = FACES[None] + 4 * np.arange(capacity, dtype=np.uint32)[:, None, None]
        self._index = idx
        self.rock = np.concatenate([self.rock, np.full(capacity - self.capacity, -1, np.int64)])
        self.capacity = capacity

    def place(self, key, centre, lod) -> None:
        """Use this chunk for cell ``key``, whose centre is ``centre`` (render frame), pebbles out to ``lod`` m from
        the camera: the engine culls it by the cell's box (a rock is filed by where it is each time it changes, so
        it lies in its cell). ``centre`` None: the stones in flight, pebbles at any distance, never culled."""
        self.key = key
        self.lod.clearSwitches()
        if centre is None:
            self.lod.addSwitch(1e9, 0.0)
            self.lod.addSwitch(0.0, 0.0)  # the points: never
            self.lod.setBounds(OmniBoundingVolume())
            self.node.show()
            return
        self.lod.addSwitch(lod, 0.0)  # the pebbles (child 0) from 0 to lod m, the points (child 1) beyond
        self.lod.addSwitch(1e5, lod)
        self.lod.setCenter(Point3(*centre))
        half = CELL / 2 + REACH[0]
        self.lod.setBounds(BoundingBox(Point3(centre[0] - half, centre[1] - half, REACH[1]),
                                       Point3(centre[0] + half, centre[1] + half, REACH[2])))
        self.node.show()

    def views(self) -> tuple:
        """The pebble buffer as (capacity, 4) and the point buffer as (capacity,) vertices (meshes.VERTEX)."""
        return vertex_view(self.mesh).reshape(-1, 4), vertex_view(self.points)

    def words(self) -> tuple:
        """The same buffers as (capacity, 4, 4) and (capacity, 4) 32-bit words, written in place: a rock's rows
        move about as plain copies of words."""
        return vertex_words(self.mesh).reshape(-1, 4, 4), vertex_words(self.points)

    def _sized(self) -> None:
        """The primitives cover slots 0 .. count - 1 only (the first 12 count entries of the index pattern): the
        engine transforms no vertex past them."""
        n = self.count
        self.tris.setVertices(self._index, 12 * n)
        self.dots.setNonindexedVertices(0, n)
        (self.node.show if n else self.node.hide)()

    def update(self, gone, stay, stay_data, arrive, arrive_data, slot_of) -> None:
        """One frame of this chunk: empty the slots ``gone`` (the rocks of the last slots move into the holes left
        below the new count), write ``stay_data`` (a rock's 4 pebble vertices and its point, as the buffers hold
        them) where the rocks ``stay`` are, and append the rocks ``arrive`` with ``arrive_data``."""
        mesh, pts = self.words()
        if len(gone):
            slots = gone
            new = self.count - len(gone)
            out = np.zeros(self.count, bool)
            out[slots] = True
            holes = slots[slots < new]
            if len(holes):
                movers = np.arange(new, self.count)[~out[new:]]
                mesh[holes] = mesh[movers]
                pts[holes] = pts[movers]
                self.rock[holes] = self.rock[movers]
                slot_of[self.rock[holes]] = holes
            self.rock[new:self.count] = -1
            self.count = new
        if len(stay):
            self._write(mesh, pts, slot_of[stay], stay_data)
        if len(arrive):
            m = len(arrive)
            if self.count + m > self.capacity:
                self._grow(max(self.count + m, int(1.5 * self.capacity)))
                mesh, pts = self.words()
            slots = np.arange(self.count, self.count + m)
            self.rock[slots] = arrive
            slot_of[arrive] = slots
            self.count += m
            self._write(mesh, pts, slots, arrive_data)
        if len(gone) or len(arrive):
            self._sized()

    @staticmethod
    def _write(mesh, pts, slots, data) -> None:
        mesh[slots], pts[slots] = data


class RockMesh:
    """The mirror of the bed and its chunks (module docstring). ``radii``: (N,) m from ``state()`` once;
    ``origin``: (3,) world m of the render frame; ``parent``: the NodePath to draw under."""

    def __init__(self, radii: np.ndarray, origin, parent: NodePath):
        n = len(radii)
        self.n = n
        self.origin = np.asarray(origin, np.float64)
        self.positions = np.zeros((n, 3))
        self.phase = np.zeros(n, np.int8)
        self.orientations = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        ids = np.arange(n)
        self._shape = templates()[ids % SHAPES] * (SIZE * radii)[:, None, None]  # (N, 4, 3), turned on apply
        self._inv_len = 1.0 / np.linalg.norm(self._shape, axis=2)
        self._base255 = 255.0 * rock_colours(ids, radii)
        # a far rock is one pixel: its lit top or its shaded side, so the far bed reads as speckle on the ground
        self._glint = np.where((ids * 2654435761) % 7 < 2, 0.6, 1.12)
        self.node = parent.attachNewNode("rocks")
        self.chunks: list[Chunk] = []
        self._by_key: dict = {}
        self._free: list[int] = []
        self.streaks = _Streaks(self.node)
        self.chunk_of = np.full(n, -1, np.int64)
        self.slot_of = np.zeros(n, np.int64)
        self.rows_written = 0  # rows written in the last apply
        self._primed = False

    def apply(self, rows, camera_move=(0.0, 0.0, 0.0)) -> None:
        """Put a ``changes()`` record into the mirror and write its rows' pebbles where their rocks are drawn;
        ``camera_move``: how far the camera moved since the last frame (m, world), for the streaks."""
        ids = np.asarray(rows.ids, np.int64)
        self.rows_written = len(ids)
        if not len(ids):
            self.streaks.draw(np.empty((0, 2, 3)), np.empty((0, 4), np.uint8))
            return
        flying = np.asarray(rows.phase) == FLYING
        before = self.positions[ids[flying]]
        self.positions[ids] = rows.positions
        self.phase[ids] = rows.phase
        if rows.orientations is not None:
            self.orientations[ids] = rows.orientations
        local = rows.positions - self.origin
        turned = rotate(self.orientations[ids], self._shape[ids])  # (k, 4, 3); the engine's quaternions are unit
        corners = local[:, None, :] + turned
        light = AMBIENT + DIFFUSE * np.maximum((turned @ SUN) * self._inv_len[ids], 0.0)  # (k, 4): n = t / |t|
        k = len(ids)
        # the rows as the buffers hold them (meshes.VERTEX), built as 32-bit words: the position's three floats
        # and the colour's four bytes, so that moving them about is plain copies of words
        shade = np.minimum(self._base255[ids][:, None, :] * light[..., None], 255.0)
        lit = np.empty((k, 4, 4), np.uint8)
        lit[..., :3] = shade
        lit[..., 3] = 255
        dot = np.empty((k, 4), np.uint8)
        dot[:, :3] = np.minimum(shade.mean(axis=1) * self._glint[ids, None], 255.0)
        dot[:, 3] = 255
        pebbles = np.empty((k, 4, 4), np.uint32)
        pebbles[..., :3] = corners.astype(np.float32).view(np.uint32)
        pebbles[..., 3] = lit.view(np.uint32)[..., 0]
        dots = np.empty((k, 4), np.uint32)
        dots[:, :3] = local.astype(np.float32).view(np.uint32)
        dots[:, 3] = dot.view(np.uint32)[:, 0]
        self._file(ids, local, (pebbles, dots))
        seg = np.stack([before + np.asarray(camera_move, np.float64), rows.positions[flying]], 1) - self.origin
        tint = np.minimum(dot[flying].astype(np.int64) * 5 // 4 + 20, 255).astype(np.uint8)  # lighter than the stone
        if not self._primed:  # the first rows (every rock) have no position before them
            seg, tint, self._primed = seg[:0], tint[:0], True
        self.streaks.draw(seg, tint)

    def _file(self, ids, local, data) -> None:
        """Each row into the chunk of its cell: in place where it stays, moved where it changed cell. The rows are
        grouped by chunk with one sort, so a frame costs one update per chunk it touches."""
        cells = np.floor(local[:, :2] * (1.0 / CELL)).astype(np.int64)
        keys = (cells[:, 0] * (1 << 32) + cells[:, 1]) << 1
        keys[np.asarray(self.phase[ids]) == FLYING] = AIR
        uniq, inverse = np.unique(keys, return_inverse=True)
        new = np.array([self._chunk_for(k) for k in uniq.tolist()], np.int64)[inverse.ravel()]
        old = self.chunk_of[ids]
        moved = old != new
        leaving = np.flatnonzero(moved & (old >= 0))
        # the slots the leavers free, read before any chunk moves a rock: an arriving rock gets a new slot
        gone = {c: self.slot_of[ids[sel]] for c, sel in _groups(old[leaving], leaving)}
        order = np.lexsort((moved, new))  # by chunk; in each, the rows that stay, then those that arrive
        data = tuple(d[order] for d in data)
        ids_o, moved_o = ids[order], moved[order]
        empty = ids[:0]
        for c, lo, hi in _runs(new[order]):
            split = lo + int(np.searchsorted(moved_o[lo:hi], True))
            self.chunks[c].update(gone.pop(c, empty), ids_o[lo:split], tuple(d[lo:split] for d in data),
                                  ids_o[split:hi], tuple(d[split:hi] for d in data), self.slot_of)
        for c, slots in gone.items():  # chunks that only lost rocks
            self.chunks[c].update(slots, empty, (), empty, (), self.slot_of)
        self.chunk_of[ids] = new
        for c in {int(x) for x in np.unique(old[leaving])}:
            chunk = self.chunks[c]
            if chunk.count == 0 and chunk.key is not None:  # a cell the bed left
                del self._by_key[chunk.key]
                chunk.key = None
                self._free.append(c)

    def _chunk_for(self, key: int) -> int:
        c = self._by_key.get(key)
        if c is None:
            if self._free:
                c = self._free.pop()
            else:
                self.chunks.append(Chunk(self.node))
                c = len(self.chunks) - 1
            if key == AIR:
                self.chunks[c].place(key, None, None)
            else:
                cell = key >> 1
                ix, iy = cell >> 32, cell - ((cell >> 32) << 32)
                if iy >= 1 << 31:
                    ix, iy = ix + 1, iy - (1 << 32)
                self.chunks[c].place(key, ((ix + 0.5) * CELL, (iy + 0.5) * CELL, 0.0), GROUND_LOD)
            self._by_key[key] = c
        return c


class _Streaks:
    """One-pixel lines for the stones in flight (module docstring), rewritten each frame."""

    def __init__(self, parent: NodePath):
        self.vdata = GeomVertexData("streaks", GeomVertexFormat.getV3c4(), Geom.UHDynamic)
        self.lines = GeomLines(Geom.UHDynamic)
        geom = Geom(self.vdata)
        geom.addPrimitive(self.lines)
        node = GeomNode("streaks")
        node.addGeom(geom)
        node.setBounds(OmniBoundingVolume())  # rewritten every frame behind the engine's back: never culled
        node.setFinal(True)
        self.node = parent.attachNewNode(node)

    def draw(self, segments, colours) -> None:
        k = len(segments)
        if self.vdata.getNumRows() < 2 * k:
            self.vdata.setNumRows(max(2 * k, 2 * self.vdata.getNumRows(), 512))
        if k:
            v = vertex_view(self.vdata)
            v["p"][: 2 * k] = segments.reshape(-1, 3)
            v["c"][: 2 * k] = np.repeat(colours, 2, axis=0)
        self.lines.setNonindexedVertices(0, 2 * k)


def _runs(sorted_keys: np.ndarray):
    """(key, start, end) of each run of equal values in ``sorted_keys``."""
    if not len(sorted_keys):
        return
    cuts = np.flatnonzero(np.diff(sorted_keys)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [len(sorted_keys)]])
    for a, b in zip(starts.tolist(), ends.tolist()):
        yield int(sorted_keys[a]), a, b


def _groups(keys: np.ndarray, values: np.ndarray):
    """(key, the values with that key) for each key in ``keys``."""
    order = np.argsort(keys, kind="stable")
    k, v = keys[order], values[order]
    for key, a, b in _runs(k):
        yield key, v[a:b]
