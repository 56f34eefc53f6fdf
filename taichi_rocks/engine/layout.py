"""The World a scene needs: its layout (sizes of the hash, the tire mask, the rays and the tile store; the rock
fields of its Plan and stepping mode) and what that costs in memory, from one list of fields.

:func:`world_layout` is what Simulation allocates with (engine/world.py ``acquire``: a new World); :func:`estimate_memory`
adds up the same fields (``world.field_specs``: rock fields from engine/rockfields.py, tile store, hash, rays,
counters, the bodies and the event buffer of impacts), so the estimate is the bytes the World's fields take and cannot go stale when a field is added.
Only the hash's entry capacity with AABB insert depends on the rocks' radii: the estimate draws them from the
scene's seed up to ``EXACT_UP_TO`` rocks and extrapolates from that many evenly spaced radii beyond.

:func:`memory_problem` / :func:`check_fits`: the refusal of a scene whose fields would not fit in this
machine's memory, a one-line SceneError naming the key that makes the demand (:func:`demand_key`: ``bed.rocks``;
``bed.radius`` when the tile store is sized for rocks packed densely on a tiny bed; ``sim.hash.table_size``,
``impacts.capacity`` when set so large); Simulation raises it before allocating, and ``taichi-rocks check``
reports it. :func:`frame_problem`: the same for the frames a render or the viewer draws (``render.resolution``
or ``--resolution``), refused before Taichi allocates them.
"""

from __future__ import annotations

import math
import os
from typing import Optional

import numpy as np

from ..config.plan import Plan
from ..config.scene import SceneError
from . import hashgrid
from .tiles import store_sizing
from .effects import effect_specs
from .impact_pass import body_table, event_capacity
from .rockfields import present
from .setup import hash_sizing, initial_rocks
from .world import field_specs, scan_in_parallel
from .worlddata import Placement

__all__ = ["world_layout", "estimate_memory", "memory_problem", "check_fits", "physical_memory", "n_tires_of",
           "demand_key", "frame_bytes", "frame_problem", "check_machine"]

EXACT_UP_TO = 1 << 20  # rocks: radii drawn from the seed up to this many (AABB insert only)


def n_tires_of(scene, plan) -> int:
    """Splashing rear tires: two per splashing vehicle, none without splashing."""
    return 2 * sum(1 for v in scene.vehicles if v.splash) if plan.splash else 0


def world_layout(scene, plan, radius) -> tuple[dict, object]:
    """The World's layout arguments of a scene (``world.acquire`` / ``World``: sizes and rock fields, not the
    tire pass's switches) and its HashSizing (engine/setup.py), for rocks of these radii."""
    n_tires = n_tires_of(scene, plan)
    sizing = hash_sizing(scene, plan, radius, n_tires)
    ray_len = max((v.tire_radius for v in scene.vehicles), default=1.0)
    store = None
    if plan.active:
        st = store_sizing(int(scene.bed.rocks), scene.bed.radius)
        store = (st.tile, st.grid, st.capacity, plan.recycle)
    layout = dict(hash_table=sizing.table, hash_entries=sizing.entries, n_tires=n_tires, substeps=plan.substeps,
                  ray_capacity=hashgrid.ray_capacity(ray_len, plan.cell_size), reorder=plan.reorder_every > 0,
                  tiles=sizing.tiles, tile_size=sizing.tile, store=store,
                  rocks=present(plan, "active" if plan.active else "full"), drawn=plan.drawn)
    if plan.impacts:  # the bodies stones hit and the event buffer (engine/impact_pass.py)
        layout.update(bodies=body_table(scene, plan).counts, events=event_capacity(scene, plan))
    return layout, sizing


def estimate_memory(scene) -> int:
    """Bytes of the scene's World on the device (see the module docstring): its groups as the World allocates
    them (engine/worlddata.py Placement: the fields, their table, row alignment) and the optional effects'
    fields."""
    world, effects, real = _specs(scene)
    return Placement(world, {}, {}).nbytes(real) + sum(s.nbytes(real) for s in effects)


def _field_bytes(scene) -> dict:
    """Bytes of each field of the scene's World, by field name."""
    world, effects, real = _specs(scene)
    return {s.name: s.nbytes(real) for s in world + effects}


def _specs(scene) -> tuple:
    """The fields of the scene's World (world.field_specs), its effects' and its precision."""
    plan = Plan.from_scene(scene)
    n = int(scene.bed.rocks)
    if plan.splash and not plan.center and n > EXACT_UP_TO:  # AABB entries: extrapolated from evenly spaced radii
        r_min, r_max = (float(r) for r in scene.bed.rock_radius)
        sample = r_min + (r_max - r_min) * (np.arange(EXACT_UP_TO) + 0.5) / EXACT_UP_TO
        layout, _ = world_layout(scene, plan, sample)
        scale = n / EXACT_UP_TO
        layout["hash_entries"] = int(math.ceil(layout["hash_entries"] * scale))
        if scene.sim.hash.table_size == "auto":
            layout["hash_table"] = int(math.ceil(layout["hash_table"] * scale))
    else:  # centre insert needs only the count (one entry per rock): any n, nothing drawn
        radius = initial_rocks(scene).radius if plan.splash and not plan.center else _Count(n)
        layout, _ = world_layout(scene, plan, radius)
    real = "f64" if scene.sim.precision == "f64" else "f32"
    # the optional effects' pools (engine/effects/); the scan's block sums where it runs in parallel (off the CPU)
    return field_specs(n, real, parallel_scan=scan_in_parallel(), **layout), effect_specs(scene, plan), real


STORE_PER_ROCK = 16  # tile-store slots per rock beyond which the bed's size, not the rock count, is to blame


def demand_key(scene, nbytes: dict) -> str:
    """The scene key that makes the largest part of the memory demand ``nbytes`` (:func:`_field_bytes`)."""
    groups = {"store": 0, "hash": 0, "events": 0, "rocks": 0}
    for name, b in nbytes.items():
        group = ("store" if name.startswith("ts_") else "hash" if name == "cell_start"
                 else "events" if name.startswith("ev_") else "rocks")
        groups[group] += b
    top = max(groups, key=groups.get)
    n = max(int(scene.bed.rocks), 1)
    if top == "store" and nbytes.get("ts_rock_id", 0) / 4 > STORE_PER_ROCK * n:
        return "bed.radius"
    if top == "hash" and scene.sim.hash.table_size != "auto":
        return "sim.hash.table_size"
    if top == "events" and scene.impacts.capacity != "auto":
        return "impacts.capacity"
    return "bed.rocks"


class _Count:
    """Stands for n radii where only their number is read (centre insert)."""

    def __init__(self, n: int):
        self.n = n

    def __len__(self) -> int:
        return self.n


def physical_memory() -> Optional[int]:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def memory_problem(scene) -> Optional[str]:
    """The one-line problem of a scene whose fields need more memory than this machine has (None if they fit
    or the machine does not say)."""
    nbytes = _field_bytes(scene)
    need, have = sum(nbytes.values()), physical_memory()
    if have and need > have:
        key = demand_key(scene, nbytes)
        got = {"bed.rocks": scene.bed.rocks, "bed.radius": f"{scene.bed.radius:g} m",
               "sim.hash.table_size": scene.sim.hash.table_size, "impacts.capacity": scene.impacts.capacity}[key]
        why = (f" ({scene.bed.rocks} rocks on {math.pi * scene.bed.radius ** 2:.3g} m^2)" if key == "bed.radius"
               else "")
        return (f"{scene.source}: {key}: needs about {need / 1e9:.1f} GB of memory{why}, more than this machine "
                f"has ({have / 1e9:.1f} GB), got {got}")
    return None


def check_fits(scene) -> None:
    """Raise SceneError (one line naming the key, :func:`demand_key`) if the scene's World would not fit in memory."""
    problem = memory_problem(scene)
    if problem:
        raise SceneError([problem])


# Bytes per pixel of a drawn frame: GGUI's colour and depth images (4 + 4), the frame read back as float32 RGBA
# (16), the uint8 frame (3), its copies queued to the PNG and video writers (3 + 3), and room for the driver's
# staging copy (4) and more.
BYTES_PER_PIXEL = 40


def frame_bytes(resolution) -> int:
    """About the memory a render's frame of ``resolution`` (width, height) takes (:data:`BYTES_PER_PIXEL`)."""
    w, h = (int(x) for x in resolution)
    return w * h * BYTES_PER_PIXEL


def frame_problem(scene, resolution=None) -> Optional[str]:
    """The one-line problem of frames (the scene's ``render.resolution``, or ``resolution`` from --resolution)
    that need more memory than this machine has; None if they fit or the machine does not say."""
    res = tuple(int(x) for x in (resolution if resolution is not None else scene.render.resolution))
    need, have = frame_bytes(res), physical_memory()
    if not have or need <= have:
        return None
    what = (f"--resolution {res[0]}x{res[1]}" if resolution is not None
            else f"{scene.source}: render.resolution")
    return (f"{what}: a {res[0]}x{res[1]} frame needs about {need / 1e9:.1f} GB of memory, more than this machine "
            f"has ({have / 1e9:.1f} GB)" + ("" if resolution is not None else f", got [{res[0]}, {res[1]}]"))


def check_machine(scene) -> None:
    """What ``taichi-rocks check`` asks of this machine: the World fits (:func:`check_fits`) and so do the
    frames (:func:`frame_problem`); SceneError, one line per problem."""
    check_fits(scene)
    problem = frame_problem(scene)
    if problem:
        raise SceneError([problem])
