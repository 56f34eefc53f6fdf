"""What a scene will do, in words: the summary ``taichi-rocks check`` prints. Works on validated scenes
(config/scene.py); no Taichi. What it costs in memory is the engine's to say (engine/layout.py
``estimate_memory``: the bytes of the fields it allocates); the summary prints the figure it is given."""

from __future__ import annotations

import math
from typing import Optional

from .effects import EFFECTS
from .plan import Plan


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


def summarise(scene, memory_bytes: Optional[int] = None) -> str:
    """A few lines describing the scene and what the simulation will do (``taichi-rocks check``), with the
    memory its fields take if ``memory_bytes`` is given (engine/layout.py ``estimate_memory``)."""
    e, sim, h, bed = scene.effects, scene.sim, scene.sim.hash, scene.bed
    on = {True: "on", False: "off"}
    plan = Plan.from_scene(scene)
    passes = plan.passes()
    width = max(len(v.name) for v in scene.vehicles)
    lines = [
        f"scene {scene.name!r} ({scene.source}): {scene.duration:g} s, seed {scene.seed}",
        f"bed: {bed.rocks} rocks, radius {bed.radius:g} m, rock radius {bed.rock_radius[0]:g}-{bed.rock_radius[1]:g} m,"
        f" follows {bed.follow!r}",
        f"vehicles ({len(scene.vehicles)}):",
        *(f"  {v.name:<{width}}  {v.path.kind:<9}  {_speed(v.path):<14}  {'splash' if v.splash else 'no splash'}"
          for v in scene.vehicles),
        f"effects: splash {on[e.splash]}, recycle {on[e.recycle]}, gravity {on[e.gravity]}, drag {e.drag},"
        f" ground {e.ground}, impacts {on[plan.impacts]}"
        + (f" ({', '.join(scene.vehicles[i].name for i in plan.targets)} hit)" if plan.impacts else "")
        + "".join(f", {name} {on[name in plan.effects]}" + (f" ({m.idle(scene)})" if m.idle(scene) else "")
                  for name, m in EFFECTS.items()),
        "passes per step: " + (", ".join(passes) or "none"),
        f"time: dt {sim.dt:g} s, {math.ceil(round(scene.duration / sim.dt, 6))} steps, integrator {sim.integrator},"
        f" detection {sim.detection} (substeps {sim.substeps}), precision {sim.precision}, origin {sim.origin}",
        f"hash: insert {h.insert}, cell size {h.cell_size}, table size {h.table_size},"
        + (f" reorder every {h.reorder_every} steps" if h.reorder_every else " never reordered"),
        f"camera: {_camera_line(scene.camera)}, {scene.render.resolution[0]}x{scene.render.resolution[1]}"
        f" at {scene.render.fps:g} fps",
    ]
    if memory_bytes is not None:
        lines.append(f"memory: about {memory_bytes / 1e6:.1f} MB for the simulation's fields (estimate)")
    return "\n".join(lines)
