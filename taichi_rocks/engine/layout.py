"""The World a scene needs: its layout (sizes of the hash, the tire mask, the rays and the tile store; the rock
fields of its Plan and stepping mode) and what that costs in memory, from one list of fields.

:func:`world_layout` is what Simulation allocates with (engine/world.py ``acquire``); :func:`estimate_memory`
adds up the same fields (``world.field_specs``: rock fields from engine/rockfields.py, tile store, hash, rays,
counters, the bodies and the event buffer of impacts), so the estimate is the bytes the World's fields take and cannot go stale when a field is added.
Only the hash's entry capacity with AABB insert depends on the rocks' radii: the estimate draws them from the
scene's seed up to ``EXACT_UP_TO`` rocks and extrapolates from that many evenly spaced radii beyond.

:func:`memory_problem` / :func:`check_fits`: the refusal of a scene whose fields would not fit in this
machine's memory, a one-line SceneError naming ``bed.rocks`` (Simulation raises it before allocating, and
``taichi-rocks check`` reports it).
"""

from __future__ import annotations

import math
import os
from typing import Optional

import numpy as np

from ..config.plan import Plan
from ..config.scene import SceneError
from . import hashgrid
from .active import store_sizing
from .effects import effect_specs
from .impact_pass import body_table, event_capacity
from .rockfields import present
from .setup import hash_sizing, initial_rocks
from .world import field_specs

__all__ = ["world_layout", "estimate_memory", "memory_problem", "check_fits", "physical_memory", "n_tires_of"]

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
    """Bytes of every Taichi field of the scene's World (see the module docstring)."""
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
    specs = field_specs(n, real, **layout) + effect_specs(scene, plan)  # the optional effects' pools (engine/effects/)
    return sum(s.nbytes(real) for s in specs)


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
    need, have = estimate_memory(scene), physical_memory()
    if have and need > have:
        return (f"{scene.source}: bed.rocks: needs about {need / 1e9:.1f} GB of memory, more than this machine "
                f"has ({have / 1e9:.1f} GB), got {scene.bed.rocks}")
    return None


def check_fits(scene) -> None:
    """Raise SceneError (one line naming bed.rocks) if the scene's World would not fit in memory."""
    problem = memory_problem(scene)
    if problem:
        raise SceneError([problem])
