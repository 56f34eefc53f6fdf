"""The impacts pass: flying stones against the bodies of the vehicles they can hit, inside the step, as events.

Runs in the step kernel of both stepping modes, compiled in only with the Plan's ``impacts`` (a scene's
``[effects] impacts`` with a body to hit), as a loop of its own after the rock loop (engine/kernels.py
``impacts_loop``): the rock loop (``rock_step``) lists every rock that flew at the step's start with its state
then (a resting or sliding stone lies below every body's underside, ``check_bodies``, and only a launch, after
the rock pass, makes one fly); the loop over that list tests them, then recycles and counts them for the hash,
so that both see where a body sent a stone. The list has room for every rock: it cannot overflow.

Per stone, per vehicle hit (``target``; not the one that threw it, whose own body is left to the fenders and
mud flaps of the launch model), in registers:
  1. the path in the vehicle's moving frame: p0 = R(-h0) (x0 - c0) with the pose at the step's start and
     p1 = R(-h1) (x1 - c1) with the pose at its end (x0, x1: the stone before and after its flight step; the
     poses come from the host, rows of the step's ``frame`` argument, :func:`pose_rows`). The body-frame path
     is the chord p0 -> p1: for yaw rates <= 1 rad/s the true relative path is within omega dt |u| dt / 4
     < 0.1 mm of it at 60 m/s, the flight's parabola within g dt^2 / 8 = 5 um of its own chord;
  2. broad phase: the chord's box grown by r against the body's box, then against each part's box;
  3. each part left: the exact swept sphere-hull test (engine/impacts.py ``swept_sphere_hull``).
The earliest contact over every part of every target wins. At its fraction t of the step the body's pose,
velocity and yaw rate are interpolated linearly (the heading through its unit vector) and the stone's velocity
is v(t) = v0 + t (v1 - v0). In the body's axes (the response's dot products do not depend on the axes):

    v_s = R(-h_t) v_centre(t) + yaw(t) z x q           the body's velocity at the contact point q
    u = R(-h_t) v(t) - v_s,   u_n = u . n  (< 0)        the relative velocity; n the outward normal at q
    u' = u_t' - e u_n n,  u_t' = u_t max(0, 1 - mu (1 + e) |u_n| / |u_t|)   (engine/impacts.py ``bounce``)

e, mu: ``[impacts] restitution, friction``. The event records u, u_n, m |u_n| and 1/2 m |u|^2 with m = 4/3 pi
rho r^3 (``MASS_PER_R3``); a contact closing slower than ``[impacts] min_speed`` bounces the same but is not
recorded (a stone resting or sliding on a body). No stone is left inside a body: the centre goes to
q + (r + slop) n (a stone that started within r, or inside: pushed out along the normal of the face of least
depth, an event with t = 0), and the rest of the step, (1 - t) dt, is flown in the body frame with u'. That
leg is tested again against the same body (a stone between bonnet and windscreen bounces several times in a
step): up to ``LEGS`` contacts in a step, each an event; a last leg that still meets the body stops the stone
at that contact, at rest relative to the body. The end of the step goes back to the local frame with the end
pose: x = c1 + R(h1) p_end, v = R(h1) u + v_centre(1) + yaw(1) z x R(h1) p_end. Gravity and drag over the leg
after a hit are those the flight step already took (an error of O(g dt), as the ground bounce's).

Host side (no kernels): the bodies of the scene (:func:`body_table`, from motion/bodies.py, the shapes the
renderer draws), the fields they are written to (:func:`write_bodies`), the event buffer's capacity
(:func:`event_capacity`), the pose rows of a step (:func:`pose_rows`) or of every step of a lookahead batch
(:func:`batch_pose_rows`: active stepping uploads them with the batch, engine/stepdata.py) and the scene check that a resting rock
passes under every body (:func:`check_bodies`). Events: engine/events.py; the Simulation drains the buffer
every ``DRAIN_EVERY`` steps and at ``impacts()`` (:class:`ImpactLog`).
"""


from dataclasses import dataclass
from typing import Optional

import numpy as np
import taichi as ti

from ..config.plan import Plan
from ..config.scene import SceneError
from ..motion.bodies import body_parts, hexahedron_planes, label_table
from .events import EVENT_DTYPE, append
from . import tumble
from .impacts import bounce, damage_class, stone_mass, surface_velocity, swept_sphere_hull
from .rockfields import FLYING
from .world import POSE_ROWS, Par

__all__ = ["DRAIN_EVERY", "LEGS", "POSE_ROWS", "Bodies", "body_table", "event_capacity", "body_problem",
           "check_bodies", "write_bodies", "pose_rows", "batch_pose_rows", "time_row", "hit_bodies", "ImpactLog"]

DRAIN_EVERY = 64  # steps between drains of the device buffer into the host's list
LEGS = 3  # contacts a stone can have with one body in one step
KEEP = 1 << 20  # events the host keeps for sim.impacts() at most (~130 MB); older ones are dropped and counted
# rows of a target's pose in the step's frame (2-vectors, float64): centre at the start and the end (local
# frame), (cos, sin) of the heading at the start and the end, velocity at the start and the end, yaw rate
C0, C1, H0, H1, V0, V1, YAW = range(POSE_ROWS)
vec2 = ti.types.vector(2, ti.f64)


# ------------------------------------------------------------------------------------------------ host side
@dataclass(frozen=True)
class Bodies:
    """The bodies stones can hit, as the device holds them: per target (vehicle index, its parts' range, its
    box in the body frame (lo, hi)) and per part (box, face planes, corners, labels, split)."""

    vehicle: np.ndarray  # (T,) int32
    parts: np.ndarray  # (T, 2) int32: first part, count
    box: np.ndarray  # (T, 6)
    part_box: np.ndarray  # (P, 6)
    planes: np.ndarray  # (P, 6, 4)
    corners: np.ndarray  # (P, 8, 3)
    labels: np.ndarray  # (P, 6, 2) int32
    split: np.ndarray  # (P,)
    floor: np.ndarray  # (T,) m: the lowest point of each body above the ground

    @property
    def counts(self) -> tuple[int, int]:
        """(T, P): the World layout's ``bodies``."""
        return len(self.vehicle), len(self.split)


def body_table(scene, plan, ground_z: float = None) -> Bodies:
    """The bodies of the plan's targets (``plan.targets``), parts from motion/bodies.py on the ground at
    ``ground_z`` (default: the scene's)."""
    gz = float(scene.world.ground_z if ground_z is None else ground_z)
    vehicle, ranges, boxes, part_boxes, planes, corners, parts, floors = [], [], [], [], [], [], [], []
    for i in plan.targets:
        body = body_parts(scene.vehicles[i], gz)
        ranges.append((len(parts), len(body.parts)))
        cs = [p.corners() for p in body.parts]
        vehicle.append(i)
        parts += body.parts
        corners += cs
        planes += [hexahedron_planes(c) for c in cs]
        part_boxes += [np.concatenate([c.min(axis=0), c.max(axis=0)]) for c in cs]
        every = np.concatenate(cs)
        boxes.append(np.concatenate([every.min(axis=0), every.max(axis=0)]))
        floors.append(float(every[:, 2].min()) - gz)
    labels, split = label_table(parts)
    as_real = lambda a, shape: np.array(a, np.float64).reshape(shape)
    return Bodies(np.array(vehicle, np.int32), np.array(ranges, np.int32).reshape(-1, 2), as_real(boxes, (-1, 6)),
                  as_real(part_boxes, (-1, 6)), as_real(planes, (-1, 6, 4)), as_real(corners, (-1, 8, 3)),
                  labels, np.asarray(split, np.float64), np.array(floors))


def event_capacity(scene, plan) -> int:
    """``[impacts] capacity``, or "auto": room for 16 events per splashing tire per step over the steps between
    drains (a power of two, at least 1024). Measured rates are far lower (a follower 10 m behind a car is hit
    a few times a second); a burst beyond it is counted as dropped, never lost silently."""
    cap = scene.impacts.capacity
    if cap != "auto":
        return int(cap)
    tires = 2 * sum(1 for v in scene.vehicles if v.splash)
    want = DRAIN_EVERY * 16 * max(tires, 1)
    return max(1024, 1 << (want - 1).bit_length())


def body_problem(scene, plan=None) -> Optional[str]:
    """The one-line problem of a scene whose resting rocks would not pass under a body that stones hit (the pass
    tests only flying stones): 2 r_max must be below every such body's underside. None if there is none."""
    plan = plan if plan is not None else Plan.from_scene(scene)
    if not plan.impacts:
        return None
    r_max = float(scene.bed.rock_radius[1])
    floors = body_table(scene, plan).floor
    k = int(np.argmin(floors))
    if 2.0 * r_max >= floors[k]:
        name = scene.vehicles[plan.targets[k]].name
        return (f"{scene.source}: bed.rock_radius: with [effects] impacts a resting rock must pass under the bodies "
                f"stones hit: 2 x the largest radius must be < {floors[k]:.3g} m, the underside of vehicle "
                f"{name!r} (0.8 x its tire_radius - 1 cm), got [{scene.bed.rock_radius[0]:g}, {r_max:g}]")
    return None


def check_bodies(scene, plan=None) -> None:
    """Raise SceneError (one line naming bed.rock_radius) for :func:`body_problem`."""
    problem = body_problem(scene, plan)
    if problem:
        raise SceneError([problem])


def write_bodies(world, bodies: Bodies, tire_vehicle) -> None:
    """The bodies and each splashing tire's vehicle (``tire_vehicle``: scene indices, tire order) into the
    World's fields (engine/world.py field_specs: allocated with impacts)."""
    tv = np.full(world.tire_vehicle.shape[0], -1, np.int32)
    tv[:len(tire_vehicle)] = tire_vehicle
    named = (("tire_vehicle", tv), ("target_vehicle", bodies.vehicle), ("target_parts", bodies.parts),
             ("target_box", bodies.box), ("part_box", bodies.part_box), ("part_planes", bodies.planes),
             ("part_corners", bodies.corners), ("part_labels", bodies.labels), ("part_split", bodies.split))
    for name, a in named:  # in their dtypes: the bits of from_numpy
        f = getattr(world, name)
        f.from_numpy(np.asarray(a).astype(f.np_dtype).reshape(f.shape + ((f.n,) if f.n > 1 else ())))


def pose_rows(prev, cur, targets, shift) -> np.ndarray:
    """The targets' poses at the step's start (``prev``) and end (``cur``: lists of VehiclePose) as rows of the
    step's frame (:data:`POSE_ROWS` per target, float64 (7 T, 2)), centres in the kernels' frame now (anchor-
    relative ``rel`` minus the origin's ``shift``)."""
    out = np.empty((len(targets), POSE_ROWS, 2))
    for k, i in enumerate(targets):
        a, b = prev[i], cur[i]
        out[k, C0] = a.rel[:2] - shift
        out[k, C1] = b.rel[:2] - shift
        out[k, H0] = np.cos(a.heading), np.sin(a.heading)
        out[k, H1] = np.cos(b.heading), np.sin(b.heading)
        out[k, V0] = a.velocity[:2]
        out[k, V1] = b.velocity[:2]
        out[k, YAW] = a.yaw_rate, b.yaw_rate
    return out.reshape(-1, 2)


def batch_pose_rows(prev, table, targets, shift) -> np.ndarray:
    """:func:`pose_rows` of every step of a lookahead batch at once, NumPy over the batch (the same bits):
    ``prev`` the poses before its first step (VehiclePose list), ``table`` the batch's PoseTable (K, V) of
    motion/vehicles.py, ``shift`` the origin's shift at each step (K, 2). Returns (K, 7 T, 2) float64."""
    tg = list(targets)
    k = len(shift)

    def column(name, attr):  # (K + 1, T): the poses before the batch, then at each of its steps
        first = [attr(prev[i]) for i in tg]
        return np.vstack([np.array(first, np.float64)[None], getattr(table, name)[:, tg]])

    rx, ry = column("rx", lambda p: p.rel[0]), column("ry", lambda p: p.rel[1])
    h = column("heading", lambda p: p.heading)
    vx, vy = column("vx", lambda p: p.velocity[0]), column("vy", lambda p: p.velocity[1])
    yaw = column("yaw_rate", lambda p: p.yaw_rate)
    cos, sin = np.cos(h), np.sin(h)
    sx, sy = np.asarray(shift, np.float64)[:, 0, None], np.asarray(shift, np.float64)[:, 1, None]
    out = np.empty((k, len(tg), POSE_ROWS, 2))
    for row, (a, b) in ((C0, (rx[:-1] - sx, ry[:-1] - sy)), (C1, (rx[1:] - sx, ry[1:] - sy)),
                        (H0, (cos[:-1], sin[:-1])), (H1, (cos[1:], sin[1:])), (V0, (vx[:-1], vy[:-1])),
                        (V1, (vx[1:], vy[1:])), (YAW, (yaw[:-1], yaw[1:]))):
        out[:, :, row, 0], out[:, :, row, 1] = a, b
    return out.reshape(k, -1, 2)


def time_row(t0_rel: float) -> np.ndarray:
    """The first row of the impacts' part of the frame: the step's start time relative to the event buffer's
    reference time (engine/events.py ``t_ref``)."""
    return np.array([[t0_rel, 0.0]])


class ImpactLog:
    """The host's side of the events of a Simulation: drains the device buffer (``buf``) every DRAIN_EVERY
    steps into a list, hands the list out at :meth:`take` and keeps it right across restores."""

    def __init__(self, buf):
        self.buf = buf
        self.chunks: list = []
        self.kept = 0
        self.lost = 0  # dropped on the host: more than KEEP waiting for take()
        self.every = DRAIN_EVERY  # steps between drains
        buf.reset(0.0)

    @property
    def dropped(self) -> int:
        return self.buf.dropped + self.lost

    def after_step(self, step: int, time: float) -> None:
        if step % self.every == 0:
            self.drain(time)

    def drain(self, time: float) -> None:
        ev = self.buf.drain(t_now=time)
        if len(ev):
            self.chunks.append(ev)
            self.kept += len(ev)
            while self.kept > KEEP and self.chunks:
                first = self.chunks.pop(0)
                self.kept -= len(first)
                self.lost += len(first)

    def take(self, time: float) -> np.ndarray:
        """Every event since the last take, in (step, rock, vehicle) order."""
        self.drain(time)
        out = np.concatenate(self.chunks) if self.chunks else np.empty(0, EVENT_DTYPE)
        self.chunks, self.kept = [], 0
        return out

    def restore(self, step: int, time: float, dropped: int = 0) -> None:
        """After a restore to step ``step`` at ``time``: the device's events are dropped, the host keeps the
        events of steps up to ``step``; the steps run from here record theirs again. ``dropped``: the events lost
        before that step (the checkpoint's count), counted on from there."""
        self.buf.reset(time)
        self.lost = int(dropped)
        self.chunks = [c[c["step"] <= step] for c in self.chunks]
        self.chunks = [c for c in self.chunks if len(c)]
        self.kept = sum(len(c) for c in self.chunks)


# ------------------------------------------------------------------------------------------------ device side
@ti.func
def _rot(cs, v):
    """R(h) v about z, ``cs`` = (cos h, sin h)."""
    return ti.Vector([cs[0] * v[0] - cs[1] * v[1], cs[1] * v[0] + cs[0] * v[1], v[2]])


@ti.func
def _unrot(cs, v):
    """R(-h) v about z."""
    return ti.Vector([cs[0] * v[0] + cs[1] * v[1], cs[0] * v[1] - cs[1] * v[0], v[2]])


@ti.func
def _row(w: ti.template(), frame: ti.template(), r):
    return ti.Vector([ti.cast(frame[r][0], w.real), ti.cast(frame[r][1], w.real)])


@ti.func
def _lift(w: ti.template(), v2):
    """A horizontal 2-vector as a 3-vector (z = 0)."""
    return ti.Vector([v2[0], v2[1], ti.cast(0.0, w.real)])


@ti.func
def _overlap(lo, hi, box, grow):
    """The box [lo, hi] meets ``box`` (lo, hi as 6 numbers) grown by ``grow``."""
    return (lo[0] <= box[3] + grow and hi[0] >= box[0] - grow and lo[1] <= box[4] + grow and hi[1] >= box[1] - grow
            and lo[2] <= box[5] + grow and hi[2] >= box[2] - grow)


@ti.func
def _first_contact(w: ti.template(), k, p0, p1, r):
    """The earliest contact of the chord p0 -> p1 (body frame of target k) with its parts: (hit, t, point,
    normal, part, face)."""
    hit, t_best, point, normal, part, face = 0, r * 0.0 + 2.0, p0, p0 * 0.0, -1, 0
    lo, hi = ti.min(p0, p1), ti.max(p0, p1)
    rng = w.target_parts[k]
    for q in range(rng[0], rng[0] + rng[1]):
        if _overlap(lo, hi, w.part_box[q], r):
            planes = ti.Matrix([[w.part_planes[q, a, b] for b in ti.static(range(4))] for a in ti.static(range(6))])
            corners = ti.Matrix([[w.part_corners[q, a, b] for b in ti.static(range(3))] for a in ti.static(range(8))])
            h, t, pt, nm, fc = swept_sphere_hull(p0, p1, r, planes, corners)
            if h != 0 and t < t_best:
                hit, t_best, point, normal, part, face = 1, t, pt, nm, q, fc
    return hit, t_best, point, normal, part, face


@ti.func
def _record(w: ti.template(), i, k, part, face, point, normal, u, un, r, t_rel, step, thrower):
    """Append the event of a contact (body frame: point, normal, relative velocity u, u_n = u . n < 0), unless it
    closes slower than MIN_SPEED."""
    if -un >= w.par[Par.MIN_SPEED]:
        m = stone_mass(r, w.par[Par.MASS_PER_R3])
        value = 0.5 * m * un * un
        if w.par[Par.DAMAGE_MOMENTUM] > 0.5:
            value = -m * un
        side = 1 if point[0] < w.part_split[part] else 0
        ev = w.events.record(time=t_rel, step=step, vehicle=w.target_vehicle[k], part=w.part_labels[part, face, side],
                             damage=damage_class(value, w.par[Par.CHIP], w.par[Par.CRACK]), point=point,
                             normal=normal, speed=u.norm(), normal_speed=-un, normal_momentum=-m * un,
                             energy=0.5 * m * u.dot(u), radius=r, rock=w.rock_id[i], thrower=thrower)
        append(w.events, ev)


@ti.func
def _write_back(w: ti.template(), i, frame: ti.template(), b, end, u):
    """Rock i's state at the step's end from its end point ``end`` and velocity ``u`` in the body frame of the
    target whose pose rows start at row ``b``: back to the local frame with the end pose. Written after each
    contact (the last one's stands), not once after the loop over the legs: on Vulkan (lavapipe) a store after
    that loop was lost."""
    h1 = _row(w, frame, b + H1)
    arm = _rot(h1, end)
    w.pos[i] = _lift(w, _row(w, frame, b + C1)) + arm
    w.vel[i] = (_rot(h1, u) + _lift(w, _row(w, frame, b + V1))
                + _row(w, frame, b + YAW)[1] * ti.Vector([-arm[1], arm[0], 0.0 * arm[2]]))
    w.phase[i] = FLYING


@ti.func
def hit_bodies(w: ti.template(), plan: ti.template(), i, x0, v0, h, frame: ti.template(), base: ti.template(),
               step):
    """Rock i flew from (x0, v0) to its state now over the step of h seconds: the impacts pass (module
    docstring) against the targets whose poses are rows ``base`` + 1 ... of ``frame``. One loop over the legs
    (the first against every target, the others against the one hit), so that the swept test is compiled
    once (inlined, it takes most of the kernel's compile time)."""
    x1, v1, r = w.pos[i], w.vel[i], w.radius[i]
    thrower = w.thrower[i]
    e, mu, slop = w.par[Par.BODY_RESTITUTION], w.par[Par.BODY_FRICTION], w.par[Par.CONTACT_SLOP]
    t_rel = ti.cast(frame[base][0], w.real)
    hit_k = -1  # the target hit in the first leg
    ht = ti.Vector([ti.cast(1.0, w.real), ti.cast(0.0, w.real)])  # its heading at that contact (cos, sin)
    pc, end = x0, x1  # the leg's path: body frame of hit_k from the second leg on
    u = v0 * 0.0  # the relative velocity in the body frame of hit_k
    left = h  # s of the step after the leg's start
    leg = 0
    while leg <= LEGS:  # until the stone meets nothing more (a for loop over the legs with an if inside
        # stops the thread on Vulkan, Taichi 1.7.4 on lavapipe: nothing after it ran)
        best_k, t_best = -1, r * 0.0 + 2.0
        point, normal, part, face = x0, x0 * 0.0, -1, 0
        for k in range(w.n_targets):
            if (leg == 0 and w.target_vehicle[k] != thrower) or (leg > 0 and k == hit_k):
                p0, p1 = pc, end
                if leg == 0:
                    b = base + 1 + POSE_ROWS * k
                    p0 = _unrot(_row(w, frame, b + H0), x0 - _lift(w, _row(w, frame, b + C0)))
                    p1 = _unrot(_row(w, frame, b + H1), x1 - _lift(w, _row(w, frame, b + C1)))
                if _overlap(ti.min(p0, p1), ti.max(p0, p1), w.target_box[k], r):
                    hit, t, q, n, pa, fa = _first_contact(w, k, p0, p1, r)
                    if hit != 0 and t < t_best:
                        best_k, t_best, point, normal, part, face = k, t, q, n, pa, fa
        if best_k < 0:
            leg = LEGS  # nothing hit: no more legs
        else:
            t = t_best
            if leg == 0:  # the body's motion at the contact, the stone's velocity relative to it
                hit_k = best_k
                b = base + 1 + POSE_ROWS * hit_k
                ht = (_row(w, frame, b + H0) * (1.0 - t) + _row(w, frame, b + H1) * t).normalized()
                vc = _lift(w, _row(w, frame, b + V0) * (1.0 - t) + _row(w, frame, b + V1) * t)
                yaw = _row(w, frame, b + YAW)
                vs = surface_velocity(_unrot(ht, vc), yaw[0] * (1.0 - t) + yaw[1] * t, point)
                u = _unrot(ht, v0 + t * (v1 - v0)) - vs
            if leg < LEGS:
                un = u.dot(normal)
                _record(w, i, hit_k, part, face, point, normal, u, un, r, t_rel + h - left * (1.0 - t), step,
                        thrower)
                u_new, _ = bounce(u, u * 0.0, normal, e, mu)
                if ti.static(plan.spin):  # the contact's impulse turns the stone (world axes; engine/tumble.py)
                    tumble.apply_impulse(w, plan, i, _rot(ht, -r * normal), _rot(ht, u_new - u))
                u = u_new
                left *= 1.0 - t
                pc = point + (r + slop) * normal
                end = pc + left * u
            else:  # the last leg still meets the body: the stone stops there, at rest on it
                end = point + (r + slop) * normal
                u = u * 0.0
            _write_back(w, i, frame, base + 1 + POSE_ROWS * hit_k, end, u)
        leg += 1
