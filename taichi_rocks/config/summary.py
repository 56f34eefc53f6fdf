"""What a scene will cost and do, in words and bytes: the memory estimate and the summary ``taichi-rocks check``
prints. Works on validated scenes (config/scene.py); no Taichi."""

from __future__ import annotations

import math
import os
from typing import Optional

from .plan import Plan


def physical_memory() -> Optional[int]:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None



def estimate_memory(scene) -> int:
    """Bytes the simulation allocates, roughly. The one place this estimate lives:

    * per rock, 8 reals (position 3, velocity 3, radius, friction; 4 bytes in f32, 8 in f64) and 4 int32
      (id, phase, slot, scratch), plus a second copy of the reals as the reorder double buffer;
    * the spatial hash: one int32 entry per (rock, cell) pair, ~1 per rock with insert = "center" and ~60 with
      "aabb"; and a table of 2 int32 per slot, with as many slots as entries unless sim.hash.table_size is set.
    """
    rocks, real = scene.bed.rocks, 4 if scene.sim.precision == "f32" else 8
    entries = rocks * (1 if scene.sim.hash.insert == "center" else 60)
    table = scene.sim.hash.table_size
    slots = table if isinstance(table, int) else entries
    return rocks * (2 * 8 * real + 4 * 4) + 4 * entries + 2 * 4 * slots


def _speed(path) -> str:
    if isinstance(path.speed, tuple):
        return f"{min(path.speed):g}-{max(path.speed):g} m/s (per point)"
    return f"{path.speed:g} m/s"


def _view_words(view: str, follow, target) -> str:
    if view == "chase":
        return f"chase view, follows {follow!r}" + (f", looks at {target!r}" if target else "")
    if view in ("driver", "bonnet"):
        return f"{view} view of {follow!r}"
    return f"{view} view of {target or follow!r}"


def _camera_line(cam) -> str:
    lines = [] if cam.shots and cam.shots[0].at == 0 else [_view_words(cam.view, cam.follow, cam.target)]
    lines += [f"{_view_words(s.view, s.follow or cam.follow, s.target or cam.target)} from {s.at:g} s"
              for s in cam.shots]
    return "; ".join(lines)


def summarise(scene) -> str:
    """A few lines describing the scene and what the simulation will do (``taichi-rocks check``)."""
    e, sim, h, bed = scene.effects, scene.sim, scene.sim.hash, scene.bed
    on = {True: "on", False: "off"}
    passes = Plan.from_scene(scene).passes()
    width = max(len(v.name) for v in scene.vehicles)
    lines = [
        f"scene {scene.name!r} ({scene.source}): {scene.duration:g} s, seed {scene.seed}",
        f"bed: {bed.rocks} rocks, radius {bed.radius:g} m, rock radius {bed.rock_radius[0]:g}-{bed.rock_radius[1]:g} m,"
        f" follows {bed.follow!r}",
        f"vehicles ({len(scene.vehicles)}):",
        *(f"  {v.name:<{width}}  {v.path.kind:<9}  {_speed(v.path):<14}  {'splash' if v.splash else 'no splash'}"
          for v in scene.vehicles),
        f"effects: splash {on[e.splash]}, recycle {on[e.recycle]}, gravity {on[e.gravity]}, drag {e.drag},"
        f" ground {e.ground}",
        "passes per step: " + (", ".join(passes) or "none"),
        f"time: dt {sim.dt:g} s, {math.ceil(round(scene.duration / sim.dt, 6))} steps, integrator {sim.integrator},"
        f" detection {sim.detection} (substeps {sim.substeps}), precision {sim.precision}, origin {sim.origin}",
        f"hash: insert {h.insert}, cell size {h.cell_size}, table size {h.table_size},"
        + (f" reorder every {h.reorder_every} steps" if h.reorder_every else " never reordered"),
        f"camera: {_camera_line(scene.camera)}, {scene.render.resolution[0]}x{scene.render.resolution[1]}"
        f" at {scene.render.fps:g} fps",
        f"memory: about {estimate_memory(scene) / 1e6:.1f} MB (estimate)",
    ]
    return "\n".join(lines)
