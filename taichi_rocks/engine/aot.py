"""The step as an ahead-of-time module (``taichi-rocks aot``, docs/native.md): what a host without Python needs to
step a Simulation's World through Taichi's C API (native/): the kernels of a step of active stepping compiled for
one backend, each kernel's argument order, the World's buffers as the Simulation built them, where each field
lies in them, and the facts of the host side of a step (engine/host.py, motion/vehicles.py, engine/impact_pass.py,
engine/events.py) that the host repeats with the same numbers.

What a module carries: active stepping (``[sim] stepping = "active"``, the default) with any switches of the
kernels (integrators, drag, detection, launch models, impacts, tumbling, the changes mirror), on ``x64`` (Taichi's
CPU backend: the step's serial variant, engine/loops.py, which gives the parallel one's bits) or ``vulkan`` (the
parallel variant). What it does not (:func:`problem`, one line naming the key): full stepping, the optional effects
(dust), a bed without rocks, and what the backend cannot run (config/arches.py).

The kernels take the World's six groups (engine/view.py ``GROUPS``) first, then 32-bit integers and arrays, never a
64-bit scalar, a vector or a returned value (the C API passes none of them): the step's inputs go through
``load_batch``'s array (engine/stepdata.py), the origin's move through the World (engine/origin.py), counts come
back in arrays (``gather_counted``, ``take_counted``), and single entries of a field are read and written with the
copy kernels of engine/worlddata.py (``read_i32``, ``write_i32``, ``read_i64``, ``write_f64``: a group, the first
element, the count, an array), as ``HostField`` does from Python.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import taichi as ti

from ..config.arches import arch_problem
from ..config.plan import Plan
from . import active, changes, events, stepdata, worlddata
from .events import COLUMNS, REF_SPAN
from .host import ORIGIN_RANGE, ORIGIN_SNAP, reach
from .impact_pass import DRAIN_EVERY, KEEP
from .origin import move_origin
from .params import IPar
from .steppers import TABLE_EVERY, TABLE_LOAD, TABLE_MIN
from .view import GROUP_NAMES, GROUPS, HEAD, REAL_SIZES, SIZES
from .world import (A0, A1, ACTIVE, B0, B1, BATCH_ROWS, CLOCK, FENDER, FLAP, FRAME_ROWS, FWD, GRID, HALF_L, HALF_W,
                    HULL, HULL_VERTICES, LEAD, MOVE, POSE_ROWS, RAY_FIELDS, SPIN, TILES, TIRE_R, VEL, CENTRE)

__all__ = ["ARCHES", "FORMAT", "problem", "export", "MEANINGS"]

ARCHES = ("x64", "vulkan")
FORMAT = "taichi-rocks module 1"  # the manifest's format and version (a host refuses another)
_TI_ARCH = {"x64": ti.x64, "vulkan": ti.vulkan}
_RUNTIME = {"x64": "cpu", "vulkan": "vulkan"}  # the backend the exporting Simulation runs on
# what a Vulkan device must have for the World's groups: 64-bit integers and floats (the i64 and f64 groups) and
# 64-bit integer atomics (the launch and recycle counts); SPIR-V without them fails to compile ("Type u64 not
# supported")
_CAPS = {"vulkan": (ti.DeviceCapability.spirv_has_int64, ti.DeviceCapability.spirv_has_float64,
                    ti.DeviceCapability.spirv_has_atomic_int64)}

#: what each field of the World holds (the manifest's "meaning"; rock fields: engine/rockfields.py)
MEANINGS = {
    "pos": "m, each listed rock's position in the local frame (world = origin + local)",
    "vel": "m/s, each listed rock's velocity", "radius": "m, each listed rock's radius",
    "friction": "static friction coefficient against the tread", "rock_id": "each listed rock's id (-1: left)",
    "phase": "0 resting, 1 flying, 2 sliding", "hit_step": "the step a rock was last launched at (-1: never)",
    "slot": "scratch: a rock's hash slot", "thrower": "the vehicle whose tire threw a rock (-1: none)",
    "spin": "rad/s, angular velocity (world axes)", "orient": "orientation quaternion (x, y, z, w)",
    "par": "the real parameters (engine/params.py Par)",
    "ipar": "the integer parameters and counts (engine/params.py IPar: N_ROCKS the active list's length, TABLE the "
            "hash slots in use)",
    "launches": "rocks launched by a tire since time 0", "recycles": "rocks recycled to the bed's leading edge",
    "origin_move": "float64 rows: the origin's move d, the origin before and after it (XY, engine/origin.py)",
    "cell_start": "the hash: each slot's first entry", "entries": "the hash: rock indices by slot",
    "claim": "the tire pass: the first tire to launch a rock", "tire_counts": "the tire pass's spans and launch count",
    "ray": "each splashing tire's ray row (engine/world.py A0 ... HULL)", "ray_cells": "the cells a tire's ray visits",
    "ray_cell_count": "the count of ray_cells per ray", "tire_cells": "each query's first and last cell",
    "ts_count": "the tile store: rocks in each slot", "ts_key": "the tile store: each slot's tile key",
    "ts_sel": "the tile store: each slot's class this step", "ts_list": "the tile store: the slots marked this step",
    "ts_tires": "the tile store: the tires marking a slot", "a_hole": "compaction: holes below the new count",
    "a_mover": "compaction: rocks above it", "a_counts": "active stepping's counters (engine/active.py)",
    "tire_box": "each tire's query box this step", "tire_keys": "each tire's first and last tile",
    "step_frame": "float64 rows of a batch's steps: centre, move, lead, grid, shift in tiles, (dt, start time)",
    "step_rays": "float64 ray rows of a batch's steps", "step_bodies": "float64 pose rows of a batch's steps",
    "tire_vehicle": "the vehicle of each splashing tire", "target_vehicle": "each body stones hit: its vehicle",
    "target_parts": "each body's parts (first, count)", "target_box": "each body's box (body frame)",
    "part_box": "each part's box", "part_planes": "each part's face planes (n, d)", "part_corners": "each part's corners",
    "part_labels": "each face's part labels (engine/events.py LABELS)", "part_split": "each part's label split",
    "body_rows": "float64: the step's start time relative to the events' reference time (row 0: (t, t_ref)), then "
                 "the pose rows of the bodies hit",
    "ev_ints": "the event buffer's integer columns", "ev_reals": "the event buffer's real columns",
    "ev_count": "events appended since the last drain", "fly_index": "the rocks that flew this step",
    "fly_x0": "their positions at the step's start", "fly_v0": "their velocities at the step's start",
    "fly_count": "their count", "drawn_pos": "the changes mirror: each rock's drawn position by id (local frame)",
    "drawn_phase": "the mirror's phase by id", "drawn_orient": "the mirror's orientation by id",
    "drawn_flag": "the mirror: listed since the last read", "drawn_list": "the mirror: the ids listed",
    "drawn_count": "the mirror: how many are listed", "health_out": "the runtime guard's counts",
}


def problem(scene, arch: str, tumble: bool = False) -> str | None:
    """The one-line reason a module of ``scene`` cannot be made for ``arch`` ("x64" or "vulkan"), naming the key,
    or None."""
    if arch not in ARCHES:
        return f"--arch: a module is made for {' or '.join(ARCHES)}, got {arch!r}"
    plan = Plan.from_scene(scene, tumble, True)
    src = scene.source
    if scene.bed.rocks <= 0:
        return f"{src}: bed.rocks: a module steps a bed of rocks, got {scene.bed.rocks}"
    if scene.sim.stepping != "active":
        return (f'{src}: sim.stepping: only active stepping is exported as a module (got "{scene.sim.stepping}"; '
                f'"active" gives the same results)')
    if plan.effects:
        name = plan.effects[0]
        return f"{src}: effects.{name}: the optional effect {name!r} is not exported in a module; turn it off"
    return arch_problem(scene, _RUNTIME[arch])


def _templates(w) -> dict:
    """A world kernel's template arguments for World ``w``: its layout and its groups (engine/view.py)."""
    out = {"w__layout": w.layout}
    out.update({f"w__{g}": a for g, a in zip(GROUP_NAMES, w.groups)})
    return out


def _kernels(sim, arch: str) -> list:
    """(name, Taichi kernel, template arguments) of every kernel of the module."""
    w, st = sim.world, sim._stepper
    sw = st._variants[arch == "x64"]  # x64: the serial variant; Vulkan: the parallel one (engine/loops.py)
    base = _templates(w)
    real = w.real
    group = dict(zip(GROUP_NAMES, w.groups))
    out = [("load_batch", stepdata.load_batch, dict(base, plan=sw["load_batch"], data=ti.ndarray(ti.f64, (1, 1)))),
           ("active_step", active.active_step, dict(base, plan=sw["active_step"])),
           ("active_finish", active.active_finish, dict(base, plan=sw["active_finish"])),
           ("move_origin", move_origin, dict(base, exact=arch == "x64"))]
    if w.drawn:
        out.append(("gather_counted", changes.gather_counted,
                    dict(base, out=ti.ndarray(ti.f64, (1, 1)), count=ti.ndarray(ti.i32, 1))))
    if w.impacts:
        out.append(("take_counted", events.take_counted,
                    dict(base, ints=ti.ndarray(ti.i32, (1, 1)), reals=ti.ndarray(real, (1, 1)),
                         count=ti.ndarray(ti.i32, 1))))
    for name, fn, g, dt, arr in (("read_i32", worlddata._read, "i1", ti.i32, "out"),
                                 ("write_i32", worlddata._write, "i1", ti.i32, "a"),
                                 ("read_i64", worlddata._read, "l1", ti.i64, "out"),
                                 ("write_f64", worlddata._write, "d1", ti.f64, "a")):
        out.append((name, fn, {"g": group[g], arr: ti.ndarray(dt, 1), "serial": True}))
    return out


def _dtype_name(dt) -> str:
    for name, t in (("f32", ti.f32), ("f64", ti.f64), ("i32", ti.i32), ("i64", ti.i64)):
        if dt == t:
            return name
    raise ValueError(f"a module argument of type {dt}")


def _arguments(kernel, targs: dict, w) -> list:
    """A kernel's arguments as the C API takes them, in order (templates left out): the World's groups, 32-bit
    integers and arrays (their element type and dimensions, from the example given)."""
    fn = getattr(kernel, "kernel", kernel)
    out = []
    group_of = {id(a): g for g, a in zip(GROUP_NAMES, w.groups)}
    for a in fn._primal.arguments:
        ann = a.annotation
        if isinstance(ann, ti.template) or ann is ti.template:
            continue
        if ann == ti.i32:
            out.append({"name": a.name, "kind": "i32"})
            continue
        v = targs[a.name]
        if id(v) in group_of:
            out.append({"name": a.name, "kind": "group", "group": group_of[id(v)]})
            continue
        out.append({"name": a.name, "kind": "array", "dtype": _dtype_name(getattr(v.dtype, "dtype", v.dtype)),
                    "ndim": len(v.shape), "element": list(getattr(v, "element_shape", ()) or ())})
    return out


def _groups(w, where: str) -> list:
    kinds = {"real": "f64" if w.real == ti.f64 else "f32", "i32": "i32", "f64": "f64", "i64": "i64"}
    return [{"name": g, "dtype": kinds[GROUPS[g][0]], "components": GROUPS[g][1], "length": int(a.shape[0]),
             "file": f"{where}/{g}.npy"} for g, a in zip(GROUP_NAMES, w.groups)]


def _fields(w) -> list:
    out = [{"name": "head", "group": "i1", "offset": 0, "shape": [len(w.placement.head)], "row": 0,
            "meaning": f"the table kernels read: per field ({HEAD} ints) its offset and dimensions, then the sizes "
                       f"{', '.join(SIZES)}; the real group r1 starts with {', '.join(REAL_SIZES)}"}]
    for name, (group, row, offset, shape) in w.placement.at.items():
        out.append({"name": name, "group": group, "offset": int(offset), "shape": [int(s) for s in shape],
                    "row": int(row), "meaning": MEANINGS.get(name, MEANINGS.get(name[3:], "") if name.startswith(
                        "ts_") else "")})
    return out


def _vehicles(sim) -> list:
    """Each vehicle's geometry as the host side uses it (motion/vehicles.py ``Fleet.rear_tires``)."""
    fleet = sim.fleet
    out = []
    for i, v in enumerate(fleet.specs):
        out.append({"name": v.name, "splash": bool(v.splash), "hit": bool(v.hit), "wheelbase": float(v.wheelbase),
                    "track": float(v.track), "tire_radius": float(v.tire_radius), "slip": float(v.slip),
                    "tread": [float(x) for x in fleet._tread[i]]})
    return out


def _host(sim) -> dict:
    """The host side's facts (engine/host.py, engine/steppers.py, engine/impact_pass.py, engine/events.py)."""
    sc, w, p, h = sim.scene, sim.world, sim.plan, sim._host
    ev = None
    if w.impacts:
        ev = {"capacity": int(w.event_capacity), "drain_every": DRAIN_EVERY, "ref_span": REF_SPAN, "keep": KEEP,
              "columns": [{"name": n, "int": bool(i), "column": c, "width": k} for n, i, c, k, _ in COLUMNS],
              "ints": events.N_INT, "reals": events.N_REAL}
    return {
        "dt": sim.dt, "floating": sc.sim.origin == "floating", "ground_z": float(sc.world.ground_z),
        "origin_snap": ORIGIN_SNAP, "origin_range": ORIGIN_RANGE, "reach": reach(sc), "follow": sim.follow,
        "splashing": list(sim.fleet.splashing) if w.n_tires else [], "n_tires": int(w.n_tires),
        "targets": [int(t) for t in p.targets] if w.impacts else [],
        "moves": bool(p.flight or p.recycle or p.splash), "splash": bool(p.splash), "impacts": bool(w.impacts),
        "spin": bool(p.spin), "drawn": bool(w.drawn), "store_tile": float(w.store_tile),
        "grid_half": float(sim._sizing.grid_half),
        "table": {"size": int(w.table_size), "auto": sc.sim.hash.table_size == "auto", "min": TABLE_MIN,
                  "load": TABLE_LOAD, "every": TABLE_EVERY},
        "ipar": {"n_rocks": int(IPar.N_ROCKS), "table": int(IPar.TABLE)},
        "batch_rows": BATCH_ROWS, "frame_rows": FRAME_ROWS,
        "frame": {"centre": CENTRE, "move": MOVE, "lead": LEAD, "grid": GRID, "tiles": TILES, "clock": CLOCK},
        "ray_fields": RAY_FIELDS, "hull_vertices": HULL_VERTICES,
        "ray": {"a0": A0, "b0": B0, "a1": A1, "b1": B1, "vel": VEL, "fwd": FWD, "spin": SPIN, "active": ACTIVE,
                "half_w": HALF_W, "half_l": HALF_L, "tire_r": TIRE_R, "fender": FENDER, "flap": FLAP, "hull": HULL},
        "pose_rows": POSE_ROWS, "step_bodies": int(w.step_bodies.shape[1]) if w.impacts else 0,
        "events": ev,
        "start": {"anchor": h.anchor.tolist(), "shift": h.shift.tolist(), "bed_center": h.bed_center.tolist(),
                  "lead": h.lead.tolist()},
    }


def export(sim, arch: str, folder) -> dict:
    """The module of Simulation ``sim`` (just built: time 0) for ``arch`` into ``folder`` (which exists): Taichi's
    files in ``module/``, the World's groups as NumPy files in ``buffers/``; returns the manifest's engine part
    (the caller adds the scene and the vehicles' drives and writes it). The Simulation must run on the backend of
    ``arch`` (x64: the CPU; a Vulkan module needs Taichi on Vulkan: the World's layout differs by backend)."""
    folder = Path(folder)
    w = sim.world
    m = ti.aot.Module(_TI_ARCH[arch], caps=list(_CAPS.get(arch, ())))
    kernels = {}
    for name, k, targs in _kernels(sim, arch):
        m.add_kernel(getattr(k, "kernel", k), template_args=targs, name=name)
        kernels[name] = {"args": _arguments(k, targs, w)}
    (folder / "module").mkdir()  # (Vulkan's writer does not make it)
    m.save(str(folder / "module"))
    (folder / "buffers").mkdir()
    for g, a in zip(GROUP_NAMES, w.groups):
        np.save(folder / "buffers" / f"{g}.npy", np.ascontiguousarray(a.to_numpy()))
    return {"format": FORMAT, "taichi": ti.__version__ if isinstance(ti.__version__, str) else
            ".".join(map(str, ti.__version__)), "arch": arch, "precision": "f64" if w.real == ti.f64 else "f32",
            "rocks": int(sim.n_rocks), "groups": _groups(w, "buffers"), "fields": _fields(w), "kernels": kernels,
            "host": _host(sim), "vehicles": _vehicles(sim)}


def dumps(manifest: dict) -> str:
    """The manifest as JSON text (floats as Python's repr: a host reads the same float64)."""
    def finite(x):
        if isinstance(x, float) and not math.isfinite(x):
            raise ValueError(f"a manifest value that is not finite: {x}")
        return x
    return json.dumps(manifest, indent=1, default=finite) + "\n"
