"""2. The peers the full step is measured against, on the very rocks and rays of a step: NumPy brute force
(every rock against every tire ray), SciPy cKDTree (build + ball queries around points along each ray), NVIDIA
Warp HashGrid (CPU device; build + a query kernel) and the streaming floor (one fused Taichi read-modify-write
pass over position and velocity: gravity and a ground clamp, the least any step over the rocks costs).

A segment-sphere test: rock (c, r) touches the ray a -> b iff |c - (a + t (b - a))| <= r for
t = clamp((c - a).(b - a) / |b - a|^2, 0, 1). The point samples along a ray are spaced s <= r_max, so a ball of
radius r_max + s / 2 around them covers every rock that can touch it.
"""

import contextlib
import io
import math

import numpy as np
import taichi as ti
from scipy.spatial import cKDTree


def ray_samples(rays: np.ndarray, r_max: float):
    """Points along each ray (spacing <= r_max) and a query radius that finds every sphere of radius
    <= r_max touching the segment."""
    pts, q = [], 0.0
    for a, b in rays:
        L = float(np.linalg.norm(b - a))
        m = max(1, int(math.ceil(L / r_max)))
        s = L / m
        q = max(q, r_max + 0.5 * s)
        f = (np.arange(m) + 0.5) / m
        pts.append(a[None, :] + f[:, None] * (b - a)[None, :])
    return np.concatenate(pts).astype(np.float32), m, q


def _touching(c, r2, rays) -> np.ndarray:
    """Which spheres (centres c, squared radii r2) touch any of the rays (segment-sphere test)."""
    hit = np.zeros(len(c), bool)
    for a, b in rays:
        d = b - a
        dd = float(d @ d)
        w = c - a
        t = np.clip((w @ d) / dd, 0.0, 1.0) if dd > 0 else np.zeros(len(c), np.float32)
        e = w - t[:, None] * d
        hit |= np.einsum("ij,ij->i", e, e) <= r2
    return hit


def numpy_brute(pos, rad, rays) -> np.ndarray:
    """Segment-sphere test of every rock against every tire ray (vectorised, float32)."""
    return _touching(pos, rad * rad, rays)


def kdtree_query(pos, rad, rays, r_max):
    tree = cKDTree(pos, leafsize=16, compact_nodes=False, balanced_tree=False)
    samples, _, q = ray_samples(rays, r_max)
    lists = tree.query_ball_point(samples, q, workers=-1)
    cand = np.unique(np.concatenate([np.asarray(x, np.int64) for x in lists])) if len(lists) else np.zeros(0, int)
    return cand[_touching(pos[cand], rad[cand] ** 2, rays)]


class WarpPeer:
    """NVIDIA Warp HashGrid build + a kernel that queries it around ray samples (CPU device)."""

    def __init__(self):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            import warp as wp  # prints a CUDA-driver warning on machines without one

            wp.config.quiet = True
            wp.init()
        self.wp = wp
        self.version = wp.__version__
        self.kernel = _warp_query_kernel(wp)
        self.grid = wp.HashGrid(128, 128, 128, device="cpu")
        self.stamp = 0

    def prepare(self, pos, rad, rays, r_max):
        wp = self.wp
        self.pts = wp.array(np.ascontiguousarray(pos, np.float32), dtype=wp.vec3, device="cpu")
        self.rad = wp.array(np.ascontiguousarray(rad, np.float32), dtype=float, device="cpu")
        self.hits = wp.zeros(len(pos), dtype=wp.int32, device="cpu")
        a = np.ascontiguousarray(rays[:, 0], np.float32)
        b = np.ascontiguousarray(rays[:, 1], np.float32)
        self.a = wp.array(a, dtype=wp.vec3, device="cpu")
        self.b = wp.array(b, dtype=wp.vec3, device="cpu")
        _, self.nsamp, self.qr = ray_samples(rays, r_max)
        self.n_rays = len(rays)

    def run(self):
        if self.stamp == 0:  # the first launch compiles the module and says so on stdout
            with contextlib.redirect_stdout(io.StringIO()):
                self._run()
        else:
            self._run()

    def _run(self):
        wp = self.wp
        self.stamp += 1
        self.grid.build(self.pts, self.qr)
        wp.launch(self.kernel, dim=self.n_rays * self.nsamp,
                  inputs=[self.grid.id, self.pts, self.rad, self.a, self.b, self.nsamp, float(self.qr),
                          self.hits, self.stamp], device="cpu")
        wp.synchronize()

    def hit_ids(self):
        return np.flatnonzero(self.hits.numpy() == self.stamp)


def _warp_query_kernel(wp):
    @wp.kernel
    def query(grid: wp.uint64, pts: wp.array(dtype=wp.vec3), rad: wp.array(dtype=float),
              a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), nsamp: int, qr: float,
              hits: wp.array(dtype=wp.int32), stamp: int):
        tid = wp.tid()
        ray = tid // nsamp
        s = tid - ray * nsamp
        pa = a[ray]
        pb = b[ray]
        d = pb - pa
        p = pa + d * ((float(s) + 0.5) / float(nsamp))
        dd = wp.dot(d, d)
        qq = wp.hash_grid_query(grid, p, qr)
        idx = int(0)
        while wp.hash_grid_query_next(qq, idx):
            c = pts[idx]
            t = float(0.0)
            if dd > 0.0:
                t = wp.clamp(wp.dot(c - pa, d) / dd, 0.0, 1.0)
            e = c - (pa + d * t)
            r = rad[idx]
            if wp.dot(e, e) <= r * r:
                hits[idx] = stamp

    return query


def start_warp(enabled: bool):
    """(the Warp peer or None, what to report about it)."""
    if not enabled:
        return None, {"available": False, "error": "skipped by the configuration (tiny run)"}
    try:
        warp = WarpPeer()
        return warp, {"available": True, "version": warp.version, "device": "cpu"}
    except Exception as exc:  # not installed, or no compiler: skip the peer, never crash
        return None, {"available": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}


@ti.kernel
def _floor_pass(pos: ti.template(), vel: ti.template(), n: ti.i32, dt: ti.f32, g: ti.f32, zmin: ti.f32):
    """The streaming floor: one fused read-modify-write of position and velocity (gravity + ground clamp)."""
    for i in range(n):
        v = vel[i]
        v[2] -= g * dt
        p = pos[i] + v * dt
        if p[2] < zmin:
            p[2] = zmin
            v = ti.Vector([0.0, 0.0, 0.0])
        pos[i] = p
        vel[i] = v


class Floor:
    """The streaming floor on fields of its own (same layout as the rock fields), loaded from a state."""

    def __init__(self, capacity: int):
        self.cap = capacity
        self.n = 0
        self.pos = ti.Vector.field(3, ti.f32, shape=capacity)
        self.vel = ti.Vector.field(3, ti.f32, shape=capacity)

    def load(self, pos, vel):
        n = len(pos)
        p = np.zeros((self.cap, 3), np.float32)
        v = np.zeros((self.cap, 3), np.float32)
        p[:n], v[:n] = pos, vel
        self.pos.from_numpy(p)
        self.vel.from_numpy(v)
        self.n = n

    def run(self):
        _floor_pass(self.pos, self.vel, self.n, 0.002, 9.81, 0.0)
