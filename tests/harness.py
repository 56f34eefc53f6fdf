"""Small direct drivers of the kernels for tests: a World from explicit rocks and rays."""



import numpy as np
import taichi as ti

from taichi_rocks.config.plan import Plan
from taichi_rocks.engine import hashgrid, rocks, tires
from taichi_rocks.engine.kernels import READS, Switches
from taichi_rocks.engine.params import dilation_cells, pack
from taichi_rocks.engine.setup import entry_capacity
from taichi_rocks.engine.world import HALF_W, RAY_FIELDS, acquire, next_prime

P = np.array([73856093, 19349663, 83492791], dtype=np.uint64)


def np_cell(p, l, dtype=np.float32):
    p = np.asarray(p, dtype=dtype)
    return np.floor(p / dtype(l)).astype(np.int64)


def np_hash(c, n):
    c = (np.asarray(c, dtype=np.int64) & 0xFFFFFFFF).astype(np.uint64)
    prod = (c * P) & np.uint64(0xFFFFFFFF)
    h = prod[..., 0] ^ prod[..., 1] ^ prod[..., 2]
    return (h % np.uint64(n)).astype(np.int64)


def np_segment_sphere(a, b, c, r):
    """Brute-force closest-point test in float64: (N,) bool."""
    a, b, c = (np.asarray(x, np.float64) for x in (a, b, c))
    d = b - a
    dd = d @ d
    t = np.zeros(len(c)) if dd == 0 else np.clip((c - a) @ d / dd, 0.0, 1.0)
    q = a + t[:, None] * d
    return np.sum((c - q) ** 2, axis=1) <= np.asarray(r, np.float64) ** 2


def tire_switches(center=True, swept=False, patch=False, ground="bounce", throw="uniform", fenders=False):
    """The switches of the tire pass (kernels.READS["hash_and_tires"]) as a Plan would give them, the others off
    (the Plan's defaults: no optional effect)."""
    return Switches(Plan(center=center, swept=swept, patch=patch, ground=ground, throw=throw, fenders=fenders),
                    READS["hash_and_tires"])


def canonical(k: int, least: int = 64) -> int:
    """The smallest power of two >= max(k, least): a probe's World sizes; its tire count is compile-time (in the
    World's layout), so that probes of nearby counts share the kernels compiled for one."""
    c = least
    while c < k:
        c *= 2
    return c


FAR = np.array([1.0e4, 1.0e4, 1.0e4])  # where the padding rocks (and, 100 m below, the padding rays) lie


def padded_rocks(pos, radius, cap: int, cell: float) -> tuple:
    """``pos`` (N, 3) and ``radius`` (N,) followed by cap - N padding rocks far away (:data:`FAR`, 4 cells
    apart), which no ray can hit."""
    n = len(pos)
    pos = np.concatenate([pos, FAR + np.arange(cap - n)[:, None] * np.array([4.0 * cell, 0.0, 0.0])])
    return pos, np.concatenate([radius, np.full(cap - n, float(radius.min()) if n else cell)])


def put_rocks(w, **arrays):
    """Whole rock fields of ``w`` (name -> one value per entry of its capacity), the others kept: all of them
    through engine/rocks.py (one copy kernel a World for both ways, not one per field and way)."""
    cap = w.pos.shape[0]
    now = rocks.read_listed(w, cap)
    for name, a in arrays.items():
        now[name] = np.asarray(a).astype(now[name].dtype).reshape(now[name].shape)
    rocks.write(w, now, cap)


class Probe:
    """A World holding given rocks, a hash built in a given mode, and rays; the tire pass's switches.

    The World's sizes are canonical (:func:`canonical`): the rocks past the ``n`` given and the rays past those
    given are padding far away (:data:`FAR`), which nothing can hit; ``hits()`` and ``slot_members()`` speak of
    the given rocks only."""

    def __init__(self, pos, radius, *, cell, insert="center", table=None, rays=(), real=ti.f32,
                 swept=False, rest_speed=1e-6, patch=False, throw="uniform", fenders=False):
        pos = np.asarray(pos, np.float64).reshape(-1, 3)
        radius = np.asarray(radius, np.float64).reshape(-1)
        n = len(pos)
        self.n, self.cell, self.center = n, cell, insert == "center"
        r_max = float(radius.max()) if n else cell
        cap = canonical(n)
        pos, radius = padded_rocks(pos, radius, cap, cell)
        entries = canonical(entry_capacity(radius, cell, self.center))
        self.table = table or next_prime(entries)
        rays = np.asarray(rays, np.float64).reshape(-1, 2, 3)
        self.swept = swept
        ray_len = float(np.max(np.linalg.norm(rays[:, 1] - rays[:, 0], axis=1))) if len(rays) else 1.0
        n_tires = canonical(len(rays), 4) if len(rays) else 0
        # a new World, zeroed; the kernels compiled for a probe of the same layout serve it
        self.w = w = acquire(self, cap, real, hash_table=self.table, hash_entries=entries, n_tires=n_tires,
                             ray_capacity=canonical(hashgrid.ray_capacity(ray_len, cell) + 8, 16))
        self.switches = tire_switches(self.center, swept, patch, "bounce", throw, fenders)
        par, ipar = pack({"N_ROCKS": cap, "CELL": cell, "R_MAX": r_max, "REST_SPEED": rest_speed, "GRAVITY": 9.81,
                          "ANGLE_MIN": np.radians(30.0), "ANGLE_MAX": np.radians(30.0), "TIE_EPS": 1e-5,
                          "DILATE": dilation_cells(r_max, cell) if self.center else 0})
        w.set_params(par, ipar)
        put_rocks(w, pos=pos, radius=radius, friction=np.full(cap, 0.5), rock_id=np.arange(cap), phase=np.zeros(cap),
                  vel=np.zeros((cap, 3)), hit_step=np.full(cap, -1))
        self.rays = rays
        hashgrid.clear_counts(w)
        hashgrid.count_all(w, self.center, 0.0, 0.0)
        self.total = hashgrid.inclusive_scan(w)
        hashgrid.scatter(w, self.center)

    def set_rays(self, prev, cur, spin=10.0, tread=None):
        """Rays prev -> cur; ``tread``: the columns from HALF_W on (engine.patch.tread_columns), or zeros. The
        World's rays past those given are padding, far away."""
        w = self.w
        pad = lambda r: np.concatenate([r, np.tile(FAR - 100.0, (w.n_tires - len(r), 2, 1))])
        prev, cur = pad(np.asarray(prev, np.float64)), pad(np.asarray(cur, np.float64))
        data = np.zeros((w.n_tires, RAY_FIELDS))
        if tread is not None:
            data[:len(tread), HALF_W:] = tread
        data[:, 0:3], data[:, 3:6] = prev[:, 0], prev[:, 1]
        data[:, 6:9], data[:, 9:12] = cur[:, 0], cur[:, 1]
        data[:, 15] = 1.0
        data[:, 17] = spin
        data[:, 18] = 1.0  # active
        w.ray.from_numpy(data.astype(w.np_real()))

    def hits(self, step=1, prev=None, tread=None):
        """Indices of rocks the rays hit (launched at `step`)."""
        w = self.w
        cur = self.rays
        self.set_rays(cur if prev is None else prev, cur, tread=tread)
        put_rocks(w, phase=np.zeros(w.pos.shape[0]))
        if not self.swept:
            tires.trace_rays(w)
        tires.tire_pass(w, self.switches, step)
        return np.flatnonzero(rocks.read_listed(w, w.pos.shape[0])["hit_step"][: self.n] == step)

    def slot_members(self):
        """slot -> set of rock indices, from the built table."""
        start = self.w.cell_start.to_numpy()
        entries = self.w.entries.to_numpy()
        members = {s: {int(i) for i in entries[start[s]:start[s + 1]] if i < self.n} for s in range(self.table)}
        return {s: m for s, m in members.items() if m}


def segment_sphere_kernel(dtype, n=4096):
    """A compiled kernel running tires.segment_hits_sphere on batches, in the given precision."""
    f = ti.Vector.field(3, dtype, shape=(n, 3))
    rr = ti.field(dtype, shape=n)
    out = ti.field(ti.i32, shape=n)
    np_dtype = np.float64 if dtype == ti.f64 else np.float32

    @ti.kernel
    def run(m: ti.i32):
        for i in range(m):
            out[i] = 1 if tires.segment_hits_sphere(f[i, 0], f[i, 1], f[i, 2], rr[i]) else 0

    def call(a, b, c, r):
        m = len(c)
        buf = np.zeros((n, 3, 3), np_dtype)
        buf[:m, 0], buf[:m, 1], buf[:m, 2] = a, b, c
        f.from_numpy(buf)
        rbuf = np.zeros(n, np_dtype)
        rbuf[:m] = r
        rr.from_numpy(rbuf)
        run(m)
        return out.to_numpy()[:m].astype(bool)

    return call
