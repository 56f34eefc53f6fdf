"""The per-step inputs of active stepping on the device: what the host decides for each step of a lookahead
batch (engine/host.py ``Frames``), uploaded once per batch, so that a step's launch takes only the step's row
``k`` in the batch and its number (scalar arguments: Taichi 1.7.4 builds a Matrix in Python for every vector
argument and handles every array argument in Python, ~70 us a launch for the old rays + frame + scalars
against ~40 us for three integers, measured by ``bench --only activity``'s launch probe).

Device fields (engine/world.py ``field_specs``): ``step_rays[k, t, :]`` (float64, the World.ray layout, the
kernels' frame) and ``step_frame[k, r]`` (2-vectors, float64; rows CENTRE, MOVE, LEAD, GRID, TILES, CLOCK of
engine/world.py; CLOCK is (dt, the step's start time)) and, with impacts, ``step_bodies[k, r]`` (2-vectors,
float64: the step's pose rows of the vehicles stones hit, engine/impact_pass.py ``batch_pose_rows``, computed
with NumPy over the batch). A step's kernel copies its rays into ``World.ray`` (one serial task: ``n_tires``
rows), with impacts its pose rows into ``World.body_rows`` after the row of its start time relative to the
event buffer's reference time (:func:`take_bodies`), and reads its frame row.

``launch_empty``, ``launch_ints`` and ``launch_arrays`` do nothing: engine/probes.py ``launch_costs`` times
what launching with a step's arguments costs in Python.

Other per-step inputs go the way of the pose rows: one more field over (k, ...) in ``field_specs`` beside
these, one more array built by :func:`batch_arrays` from the batch, one more argument of :func:`load_batch`,
read by the step's kernel at row ``k`` like ``step_frame``.

The reference time (engine/events.py ``t_ref``) changes at a drain, in the middle of a batch too: the host
keeps it in ``body_rows[0][1]`` (:func:`put_t_ref`, when it changed) and the kernel subtracts it from the
step's start time in float64, the operation the host does for full stepping (engine/steppers.py
``with_bodies``: (time - dt) - t_ref), so the row has the same bits.
"""

import numpy as np
import taichi as ti

from .loops import top_loop
from .world import BATCH_ROWS, CLOCK, FRAME_ROWS, RAY_FIELDS, IPar
from .view import world_kernel

vec2 = ti.types.vector(2, ti.f64)


def batch_arrays(centre, move, lead, grid, shift, dt, tile: float, rays, start=None, bodies=None) -> tuple:
    """The batch's device rows as NumPy: (rays (K, T, RAY_FIELDS) or a dummy, frame (K, FRAME_ROWS, 2), bodies
    (K, 7 T, 2) or a dummy), from (K, 2) arrays of the bed centre (local), its move, its lead, the tire mask's
    corner and the origin's shift (m; stored in tiles: whole numbers), the steps' length ``dt`` (K,), their
    rays (K, T, RAY_FIELDS) or None without tires and, with impacts, their start times ``start`` (K,) and pose
    rows ``bodies`` (K, 7 T, 2; engine/impact_pass.py)."""
    k = len(centre)
    if k > BATCH_ROWS:
        raise ValueError(f"a batch holds at most {BATCH_ROWS} steps, got {k}")
    frame = np.zeros((k, FRAME_ROWS, 2))
    frame[:, 0], frame[:, 1], frame[:, 2], frame[:, 3] = centre, move, lead, grid
    frame[:, 4] = np.asarray(shift, np.float64) / tile
    frame[:, 5, 0] = dt
    if start is not None:
        frame[:, 5, 1] = start
    data = np.zeros((1, 1, RAY_FIELDS)) if rays is None else np.ascontiguousarray(rays, np.float64)
    poses = np.zeros((1, 1, 2)) if bodies is None else np.ascontiguousarray(bodies, np.float64)
    return data, frame, poses


def packed(w, rays: np.ndarray, frame: np.ndarray, bodies: np.ndarray) -> np.ndarray:
    """The arrays of :func:`batch_arrays` as the one (K, width) float64 array :func:`load_batch` takes, row k:
    the step's frame rows (FRAME_ROWS x 2), its rays (n_tires x RAY_FIELDS, with tires) and its pose rows (the
    World's ``step_bodies`` row, with impacts; dummies and rows past them zero). One array argument: Taichi 1.7.4
    handles each array argument in Python at every launch (a third of the launch's cost for three)."""
    k = len(frame)
    parts = [frame.reshape(k, FRAME_ROWS * 2)]
    if w.n_tires:
        parts.append(rays.reshape(k, w.n_tires * RAY_FIELDS) if len(rays) == k else np.zeros((k, w.n_tires * RAY_FIELDS)))
    if w.impacts:
        width = 2 * w.step_bodies.shape[1]
        b = np.zeros((k, width))
        if len(bodies) == k:
            b[:, :bodies.shape[1] * 2] = bodies.reshape(k, -1)
        parts.append(b)
    return np.ascontiguousarray(np.concatenate(parts, axis=1) if len(parts) > 1 else parts[0])


# What each offloaded task of load_batch does (the kernel profiler names tasks by index; see active.TASKS)
TASKS = {"load_batch": ("(serial: bounds)", "batch upload: frames, tire rays, pose rows")}
SERIAL_TASKS = {"load_batch": ("serial variant: batch upload: frames, tire rays, pose rows",)}  # engine/loops.py


@world_kernel
def load_batch(w: ti.template(), plan: ti.template(), data: ti.types.ndarray(dtype=ti.f64, ndim=2)):
    """A batch's rows (:func:`packed`) into ``step_frame``, ``step_rays`` and ``step_bodies`` (one launch per
    batch): one loop over the batch's steps, each copying its rows (a loop per field would be a task per field to
    compile with every World, for a few kilobytes). ``plan``: the step's variant (engine/loops.py)."""
    top_loop(plan)
    for k in range(data.shape[0]):
        for r in range(FRAME_ROWS):
            w.step_frame[k, r] = ti.Vector([data[k, 2 * r], data[k, 2 * r + 1]])
        if ti.static(w.n_tires > 0):
            for t, f in ti.ndrange(w.n_tires, RAY_FIELDS):
                w.step_rays[k, t, f] = data[k, 2 * FRAME_ROWS + t * RAY_FIELDS + f]
        if ti.static(w.impacts):
            base = 2 * FRAME_ROWS + w.n_tires * RAY_FIELDS
            for r in range(w.step_bodies.shape[1]):
                w.step_bodies[k, r] = ti.Vector([data[k, base + 2 * r], data[k, base + 2 * r + 1]])


def put_t_ref(w, t_ref: float) -> None:
    """The event buffer's reference time into ``body_rows[0][1]`` (module docstring), outside a step."""
    w.body_rows[0] = [0.0, float(t_ref)]


@ti.func
def take_bodies(w: ti.template(), k):
    """Step row ``k``'s impacts rows into ``World.body_rows`` (the layout engine/impact_pass.py ``hit_bodies``
    reads): its start time relative to the reference time (float64: the host's subtraction), then its pose
    rows; one serial task (1 + 7 T rows)."""
    ti.loop_config(serialize=True)
    for r in range(w.body_rows.shape[0]):
        if r == 0:
            t_ref = w.body_rows[0][1]
            w.body_rows[0] = ti.Vector([w.step_frame[k, CLOCK][1] - t_ref, t_ref])
        else:
            w.body_rows[r] = w.step_bodies[k, r - 1]


@ti.func
def step_frame(w: ti.template(), h, centre, move, lead, grid):
    """The step's frame (world.frame_type, ``w.frame_type``) of its parts, each in the World's precision."""
    return w.frame_type(h=h, centre=centre, move=move, lead=lead, grid=grid)


@ti.func
def frame_row(w: ti.template(), k, r: ti.template()):
    """Row ``r`` of step ``k``'s frame in the World's precision (a 2-vector)."""
    return ti.cast(w.step_frame[k, r], w.real)


# ------------------------------------------------------------------------------------------------ launch probe
@ti.kernel
def launch_empty():
    pass


@world_kernel
def launch_ints(w: ti.template(), plan: ti.template(), k: ti.i32, step: ti.i32, check_all: ti.i32):
    w.ipar[IPar.N_ROCKS] += 0 * (k + step + check_all)


@world_kernel
def launch_arrays(w: ti.template(), plan: ti.template(), rays: ti.types.ndarray(dtype=ti.f64, ndim=2),
                  frame: ti.types.ndarray(dtype=vec2, ndim=1), dt: ti.f64, step: ti.i32, check_all: ti.i32):
    w.ipar[IPar.N_ROCKS] += 0 * (step + check_all)
