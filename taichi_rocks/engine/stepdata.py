"""The per-step inputs of active stepping on the device: what the host decides for each step of a lookahead
batch (engine/host.py ``Frames``), uploaded once per batch, so that a step's launch takes only the step's row
``k`` in the batch and its number (scalar arguments: Taichi 1.7.4 builds a Matrix in Python for every vector
argument and handles every array argument in Python, ~70 us a launch for the old rays + frame + scalars
against ~40 us for three integers, measured by ``bench --only activity``'s launch probe).

Device fields (engine/world.py ``field_specs``): ``step_rays[k, t, :]`` (float64, the World.ray layout, the
kernels' frame) and ``step_frame[k, r]`` (2-vectors, float64; rows CENTRE, MOVE, LEAD, GRID, TILES, CLOCK of
engine/world.py). A step's kernel copies its rays into ``World.ray`` (one serial task: ``n_tires`` rows) and
reads its frame row.

``launch_empty``, ``launch_ints`` and ``launch_arrays`` do nothing: engine/probes.py ``launch_costs`` times
what launching with a step's arguments costs in Python.

Other per-step inputs (the vehicle bodies' poses for stones hitting them): one more field over (k, ...) in
``field_specs`` beside these, one more array built by :func:`batch_arrays` from the batch, one more argument
of :func:`load_batch`, read by the step's kernel at row ``k`` like ``step_frame``.
"""

import numpy as np
import taichi as ti

from .world import BATCH_ROWS, FRAME_ROWS, RAY_FIELDS, IPar

vec2 = ti.types.vector(2, ti.f64)


def batch_arrays(centre, move, lead, grid, shift, dt, tile: float, rays) -> tuple:
    """The batch's device rows as NumPy: (rays (K, T, RAY_FIELDS) or a dummy, frame (K, FRAME_ROWS, 2)), from
    (K, 2) arrays of the bed centre (local), its move, its lead, the tire mask's corner and the origin's shift
    (m; stored in tiles: whole numbers), the steps' length ``dt`` (K,) and their rays (K, T, RAY_FIELDS) or
    None without tires."""
    k = len(centre)
    if k > BATCH_ROWS:
        raise ValueError(f"a batch holds at most {BATCH_ROWS} steps, got {k}")
    frame = np.zeros((k, FRAME_ROWS, 2))
    frame[:, 0], frame[:, 1], frame[:, 2], frame[:, 3] = centre, move, lead, grid
    frame[:, 4] = np.asarray(shift, np.float64) / tile
    frame[:, 5, 0] = dt
    data = np.zeros((1, 1, RAY_FIELDS)) if rays is None else np.ascontiguousarray(rays, np.float64)
    return data, frame


# What each offloaded task of load_batch does (the kernel profiler names tasks by index; see active.TASKS)
TASKS = {"load_batch": ("(serial: bounds)", "batch upload: frames", "(serial: bounds)",
                        "batch upload: tire rays")}


@ti.kernel
def load_batch(w: ti.template(), rays: ti.types.ndarray(dtype=ti.f64, ndim=3),
               frame: ti.types.ndarray(dtype=vec2, ndim=2)):
    """A batch's rows into ``step_frame`` and ``step_rays`` (one launch per batch)."""
    for k, r in ti.ndrange(frame.shape[0], FRAME_ROWS):
        w.step_frame[k, r] = frame[k, r]
    if ti.static(w.n_tires > 0):
        for k, t, f in ti.ndrange(rays.shape[0], w.n_tires, RAY_FIELDS):
            w.step_rays[k, t, f] = rays[k, t, f]


@ti.func
def take_rays(w: ti.template(), plan: ti.template(), k):
    """Step row ``k``'s tire rays into ``World.ray`` (the layout every tire function reads), in the World's
    precision: one serial task (a handful of tires)."""
    if ti.static(plan.splash):
        ti.loop_config(serialize=True)
        for t, f in ti.ndrange(w.n_tires, RAY_FIELDS):
            w.ray[t, f] = ti.cast(w.step_rays[k, t, f], w.real)


@ti.func
def frame_row(w: ti.template(), k, r: ti.template()):
    """Row ``r`` of step ``k``'s frame in the World's precision (a 2-vector)."""
    return ti.cast(w.step_frame[k, r], w.real)


# ------------------------------------------------------------------------------------------------ launch probe
@ti.kernel
def launch_empty():
    pass


@ti.kernel
def launch_ints(w: ti.template(), plan: ti.template(), k: ti.i32, step: ti.i32, check_all: ti.i32):
    w.ipar[IPar.N_ROCKS] += 0 * (k + step + check_all)


@ti.kernel
def launch_arrays(w: ti.template(), plan: ti.template(), rays: ti.types.ndarray(dtype=ti.f64, ndim=2),
                  frame: ti.types.ndarray(dtype=vec2, ndim=1), dt: ti.f64, step: ti.i32, check_all: ti.i32):
    w.ipar[IPar.N_ROCKS] += 0 * (step + check_all)
