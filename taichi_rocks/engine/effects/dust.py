"""Dust's kernels and host side ([effects] dust): emission behind each splashing vehicle, the wake's lift,
relaxation towards the air with the Stokes response time, settling at the Stokes terminal velocity, turbulent
diffusion as a random walk, fading; a ring of ``capacity`` slots. The physics and its source (Chen, Fu & Wegman
1999, with the proxies named): config/effects/dust.py, which also declares the fields, stream and parameters.

One launch a dust step (``[dust] step``, whole simulation steps: :func:`dust_step`: every slot moves, then the step's new particles are placed) and one a read
(:func:`dust_read`). Positions are in the kernels' local frame (world = origin + local) and move with the
floating origin. Random numbers: engine/randomness.py ``uniform01(seed, particle number, step, stream)`` for an
emission, ``(seed, slot, step, stream)`` for the random walk (a slot holds one particle at a time).
"""

import math

import numpy as np
import taichi as ti

from ...config.effects import dust as decl
from ..randomness import uniform01
from ..trees import FieldTrees, Pool
from ..world import FieldSpec

NAME = decl.NAME
SQRT3 = math.sqrt(3.0)  # a uniform in [-sqrt 3, sqrt 3] has unit variance
# the kernels' parameters (an array argument): see pack_params
CARRY, LIFT, WAKE_TIME, WIND_X, WIND_Y, DIFFUSION, TAU, GRAVITY, FADE, LIFE, OPACITY, SPREAD, HEIGHT, GROUND = range(14)
N_PAR = 14
# a source row (one per vehicle that emits this step): its body centre at ground level (local), velocity,
# heading, half width, half length, speed; and its ints: first new particle's index in the step, count, first
# slot, particle number (mod 2^32, as int32 bits)
X, Y, Z, VX, VY, VZ, FX, FY, HALF_W, HALF_L, SPEED = range(11)
N_SRC = 11
_POOL = Pool()


def specs(table, dtype_real: str = "real") -> list:
    """The fields of a pool (engine/world.py FieldSpec): the declaration's FIELDS over ``capacity`` slots."""
    cap = decl.capacity(table)
    return [FieldSpec(name, dtype, n, (cap,)) for name, dtype, n in decl.FIELDS]


class DustFields:
    """The pool's Taichi fields (leased per (capacity, precision): kernels compile once per fields object)."""

    def __init__(self, table, real):
        self.trees = FieldTrees()
        for spec in specs(table):
            setattr(self, spec.name, self.trees.place(spec, real))
        self.trees.finalize()
        self.owner = None


def pack_params(table, gravity: float, viscosity: float, ground_z: float) -> np.ndarray:
    """The kernels' parameters (f32), the response time tau_p = rho_p d^2 / (18 mu) (inf: no drag)."""
    par = np.zeros(N_PAR, np.float32)
    tau = table.density * table.diameter ** 2 / (18.0 * viscosity) if viscosity > 0 else 3.0e38
    par[[CARRY, LIFT, WAKE_TIME, WIND_X, WIND_Y, DIFFUSION, TAU, GRAVITY, FADE, LIFE, OPACITY, SPREAD, HEIGHT,
         GROUND]] = (table.carry, table.lift, table.wake_time, table.wind[0], table.wind[1], table.diffusion, tau,
                     gravity, table.fade, table.life, table.opacity, table.spread, table.height, ground_z)
    return par


@ti.func
def _air(f: ti.template(), i, par: ti.template()):
    """The air's velocity at slot i: the wake's (with its updraft), decayed with the particle's age, plus the
    wind."""
    decay = ti.exp(-f.dust_age[i] / par[WAKE_TIME])
    return f.dust_wake[i] * decay + ti.Vector([par[WIND_X], par[WIND_Y], 0.0])


@ti.kernel
def dust_step(f: ti.template(), par: ti.types.ndarray(dtype=ti.f32, ndim=1),
              src: ti.types.ndarray(dtype=ti.f32, ndim=2), srci: ti.types.ndarray(dtype=ti.i32, ndim=2),
              n_src: ti.i32, n_new: ti.i32, shift: ti.types.vector(3, ti.f32), dt: ti.f32, seed: ti.i32,
              step: ti.i32):
    """One step: every slot moves by ``-shift`` (the origin's move), live particles drift (config/effects/dust.py
    stages 2 and 3), then the step's ``n_new`` particles are placed in their slots (stage 1)."""
    cap = f.dust_age.shape[0]
    for i in range(cap):
        f.dust_pos[i] -= shift
        age = f.dust_age[i]
        if age >= 0.0 and age < par[LIFE]:
            p = f.dust_pos[i]
            if p[2] > par[GROUND]:  # airborne; on the ground it is deposited and stays
                u = _air(f, i, par)
                tau = par[TAU]
                a = ti.exp(-dt / tau)
                b = dt if dt < 1.0e-4 * tau else tau * (1.0 - a)  # tau (1 - a), exact to O((dt/tau)^2)
                v = u + (f.dust_vel[i] - u) * a
                v[2] -= par[GRAVITY] * b  # settling: v_s (1 - a) = g tau (1 - a)
                walk = ti.sqrt(2.0 * par[DIFFUSION] * dt) * SQRT3
                for k in ti.static(range(3)):
                    p[k] += v[k] * dt + walk * (2.0 * uniform01(seed, i, step, decl.S_WALK_X + k) - 1.0)
                if p[2] <= par[GROUND]:
                    p[2] = par[GROUND]
                    v = ti.Vector([0.0, 0.0, 0.0])
                f.dust_pos[i] = p
                f.dust_vel[i] = v
            f.dust_age[i] = age + dt
    for j in range(n_new):
        s = 0
        for r in range(n_src):  # the source of new particle j: a handful of vehicles, scanned
            if srci[r, 0] <= j:
                s = r
        k = j - srci[s, 0]
        slot = (srci[s, 2] + k) % cap
        pid = ti.cast(srci[s, 3], ti.u32) + ti.cast(k, ti.u32)
        fx, fy = src[s, FX], src[s, FY]
        across = src[s, HALF_W] * (2.0 * uniform01(seed, pid, step, decl.S_ACROSS) - 1.0)
        behind = src[s, HALF_L] + par[SPREAD] * uniform01(seed, pid, step, decl.S_ALONG)
        up = par[HEIGHT] * uniform01(seed, pid, step, decl.S_UP)
        f.dust_pos[slot] = ti.Vector([src[s, X] - fx * behind - fy * across, src[s, Y] - fy * behind + fx * across,
                                      src[s, Z] + up])
        lift = par[LIFT] * src[s, SPEED] * (0.5 + uniform01(seed, pid, step, decl.S_LIFT))
        wake = ti.Vector([par[CARRY] * src[s, VX], par[CARRY] * src[s, VY], lift])
        f.dust_wake[slot] = wake
        f.dust_vel[slot] = wake
        f.dust_age[slot] = 0.0


@ti.kernel
def dust_read(f: ti.template(), par: ti.types.ndarray(dtype=ti.f32, ndim=1), out: ti.types.ndarray(ndim=2)):
    """Every slot's local position and opacity alpha = opacity exp(-age / fade) for 0 <= age < life, else 0."""
    for i in range(f.dust_age.shape[0]):
        age = f.dust_age[i]
        alpha = 0.0
        if age >= 0.0 and age < par[LIFE]:
            alpha = par[OPACITY] * ti.exp(-age / par[FADE])
        for k in ti.static(range(3)):
            out[i, k] = f.dust_pos[i][k]
        out[i, 3] = alpha


class Dust:
    """The dust of one Simulation: its pool (leased), the emission's host side, the step hook."""

    def __init__(self, scene, real):
        self.table = table = scene.dust
        self.scene = scene
        self.capacity = decl.capacity(table)
        self.fields = _POOL.lease(self, (self.capacity, str(real)), lambda: DustFields(table, real), _clear)
        self.sources = [i for i, v in enumerate(scene.vehicles) if v.splash]
        self.half = np.array([[0.5 * scene.vehicles[i].width, 0.5 * scene.vehicles[i].length]
                              for i in self.sources], np.float32).reshape(-1, 2)
        self.seed = int(scene.seed)
        self._out = np.zeros((self.capacity, 4), np.float32)
        self.reset()

    def reset(self, origin=None) -> None:
        """No particle, nothing carried (the start, and a restore of a checkpoint saved without dust)."""
        _clear(self.fields)
        self.carried = np.zeros(len(self.sources))  # fractions of a particle, per source
        self.emitted = 0  # particles since the start (particle numbers 0 .. emitted - 1)
        self.pending = 0.0  # s of simulation steps since the dust last moved
        self.origin = None if origin is None else np.asarray(origin, np.float64).copy()

    def counts(self, speeds, dt: float) -> np.ndarray:
        """Whole particles each source emits this step (N' dt plus what was carried, the fraction kept)."""
        self.carried += decl.emission_rate(np.asarray(speeds, np.float64), self.table) * dt
        n = np.floor(self.carried)
        self.carried -= n
        return n.astype(np.int64)

    def after_step(self, poses, origin, step: int, dt: float) -> None:
        """The hook (config/effects/dust.py HOOK "after_step"): the vehicles' poses at the step's end. The dust
        moves once the steps since its last move add up to its own step ([dust] step)."""
        self.pending += dt
        if self.pending < self.table.step * (1.0 - 1e-9):
            return
        dt, self.pending = self.pending, 0.0
        origin = np.asarray(origin, np.float64)
        shift = np.zeros(3) if self.origin is None else origin - self.origin
        self.origin = origin.copy()
        ps = [poses[i] for i in self.sources]
        n = self.counts([p.speed for p in ps], dt)
        placed = newest(n, self.capacity)
        keep = np.flatnonzero(placed)
        src = np.zeros((max(len(keep), 1), N_SRC), np.float32)
        srci = np.zeros((max(len(keep), 1), 4), np.int32)
        start = 0
        for r, s in enumerate(keep):
            p = ps[s]
            src[r, [X, Y, Z]] = np.asarray(p.position, np.float64) - origin
            src[r, [VX, VY, VZ]] = p.velocity
            src[r, [FX, FY]] = (math.cos(p.heading), math.sin(p.heading))
            src[r, [HALF_W, HALF_L]] = self.half[s]
            src[r, SPEED] = abs(p.speed)
            number = self.emitted + int(n[:s + 1].sum()) - int(placed[s])  # its first placed particle's number
            srci[r] = (start, placed[s], number % self.capacity, np.uint32(number & 0xFFFFFFFF).view(np.int32))
            start += int(placed[s])
        par = self.params(origin)
        dust_step(self.fields, par, src, srci, len(keep), start, ti.Vector([float(x) for x in shift]),
                  float(dt), self.seed, int(step))
        self.emitted += int(n.sum())

    def coast(self, poses, origin, step: int, dt: float) -> None:
        """Steps taken as one (coasting: every vehicle that matters has stopped, so none emits): one step of
        the whole interval (exact for the settling; the wake's decay is taken at its start)."""
        self.after_step(poses, origin, step, dt)

    def saved(self) -> dict:
        """What a checkpoint holds of the dust (engine/records.py Checkpoint ``effects``): every slot's fields
        (the declaration's FIELDS, by their names), the carried fractions, the particles emitted so far, the time
        since the dust last moved and the origin its positions are relative to (NaN: not moved yet)."""
        out = {name: getattr(self.fields, name).to_numpy() for name, _, _ in decl.FIELDS}
        out.update(dust_carried=self.carried.copy(), dust_emitted=np.int64(self.emitted),
                   dust_pending=np.float64(self.pending),
                   dust_origin=np.full(3, np.nan) if self.origin is None else self.origin.copy())
        return out

    def problem(self, data: dict):
        """What is wrong with the dust of checkpoint ``data`` for this dust (its keys are :meth:`saved`'s), or
        None; a checkpoint without them (saved before dust was in checkpoints) is fine."""
        keys = self.saved_keys()
        there = [k for k in keys if k in data]
        if not there:
            return None
        if len(there) < len(keys):
            return f"checkpoint: no {next(k for k in keys if k not in data)}"
        age = np.asarray(data["dust_age"])
        for name, _, width in decl.FIELDS:
            a = np.asarray(data[name])
            shape = (self.capacity,) + ((width,) if width > 1 else ())
            if a.shape != shape or a.dtype.kind != "f":
                return f"checkpoint: {name} must be {shape} numbers (one row per slot of [dust] capacity)"
            if not np.isfinite(a if name == "dust_age" else a[age >= 0]).all():  # a free slot's are never read
                return f"checkpoint: {name} must be finite"
        carried = np.asarray(data["dust_carried"])
        if carried.shape != self.carried.shape or not ((carried >= 0) & (carried < 1)).all():
            return f"checkpoint: dust_carried must be {len(self.carried)} fractions in [0, 1)"
        emitted = np.asarray(data["dust_emitted"])
        if emitted.shape != () or emitted.dtype.kind not in "iu" or int(emitted) < 0:
            return "checkpoint: dust_emitted must be a whole number >= 0"
        if not 0 <= float(data["dust_pending"]) < 1e6:
            return "checkpoint: dust_pending must be a time >= 0"
        if np.asarray(data["dust_origin"]).shape != (3,):
            return "checkpoint: dust_origin must be 3 numbers"
        return None

    @staticmethod
    def saved_keys() -> tuple:
        return tuple(name for name, _, _ in decl.FIELDS) + ("dust_carried", "dust_emitted", "dust_pending",
                                                           "dust_origin")

    def load(self, data: dict, origin) -> None:
        """The dust of checkpoint ``data`` back (checked by :meth:`problem`); none saved: it starts empty."""
        if self.saved_keys()[0] not in data:
            self.reset(origin)
            return
        for name, _, _ in decl.FIELDS:
            f = getattr(self.fields, name)
            f.from_numpy(np.asarray(data[name]).astype(np.float64 if f.dtype == ti.f64 else np.float32))
        self.carried = np.array(data["dust_carried"], np.float64)
        self.emitted = int(data["dust_emitted"])
        self.pending = float(data["dust_pending"])
        o = np.asarray(data["dust_origin"], np.float64)
        self.origin = None if np.isnan(o).any() else o.copy()

    def params(self, origin) -> np.ndarray:
        w = self.scene.world
        return pack_params(self.table, w.gravity, w.air_viscosity, w.ground_z - float(origin[2]))

    def arrays(self, origin) -> dict:
        """The live particles: "positions" (K, 3) world m (float64), "opacity" (K,) in (0, 1], oldest slot
        first."""
        origin = np.asarray(origin, np.float64)
        dust_read(self.fields, self.params(origin), self._out)
        live = self._out[:, 3] > 0.0
        return {"positions": self._out[live, :3].astype(np.float64) + origin,
                "opacity": self._out[live, 3].copy()}


def newest(n: np.ndarray, capacity: int) -> np.ndarray:
    """Of ``n[s]`` particles each source emits in a dust step (numbered in source order), how many to place: the
    newest ``capacity`` of them in all (a ring of ``capacity`` slots keeps only those), the older ones of the
    first sources left out. The kernel then places at most ``capacity`` particles, each in a slot of its own
    (two in one slot would race), whatever the rate."""
    n = np.asarray(n, np.int64)
    after = np.cumsum(n[::-1])[::-1] - n  # particles of the sources after each one
    return np.clip(capacity - after, 0, n)


def _clear(fields) -> None:
    fields.dust_age.fill(-1.0)  # a free slot; the others' values are never read before it is filled
