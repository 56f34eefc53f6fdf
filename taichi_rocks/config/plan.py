"""What a scene asks the simulation to do: which passes run and with which settings (no Taichi here)."""

from __future__ import annotations

from dataclasses import dataclass

from . import models
from .effects import effects_on


@dataclass(frozen=True)
class Plan:
    """Decided once from the scene. Only launched rocks ever leave the ground, so flight runs only with
    splashing tires; the hash table exists only if a tire queries it. The kernels read these switches at
    compile time (each kernel the ones it needs: engine/kernels.py, Switches).

    Each field's default is its "off": no pass runs, no optional effect, the settings at the scene format's
    defaults (config/models.py). ``Plan(**switches)`` is the plan of a probe or a test that runs one kernel
    with the switches it chooses (engine/probes.py, tests/harness.py): a switch added here, or an effect's,
    is off there without a word."""

    splash: bool = False  # hash build + tire pass
    flight: bool = False
    recycle: bool = False
    center: bool = models.Hash.model_fields["insert"].default == "center"  # centre insert (else AABB)
    scope_all: bool = False  # hash every rock (else only those near a tire's query region)
    swept: bool = False  # a swept query box, no ray cells ("swept" and "patch" detection)
    patch: bool = False  # the tread's swept footprint counts ("patch" detection)
    throw: str = models.Launch.model_fields["model"].default  # launch model: "tread" | "uniform"
    fenders: bool = False  # fender and mud-flap test (tread model)
    substeps: int = 1
    reorder_every: int = 0
    integrator: str = models.Sim.model_fields["integrator"].default
    gravity: bool = False
    drag: str = models.Effects.model_fields["drag"].default
    ground: str = models.Effects.model_fields["ground"].default
    cell_size: float = 0.0
    active: bool = False  # activity-proportional stepping: resting rocks in ground tiles (engine/active.py)
    impacts: bool = False  # flying rocks against the vehicles' bodies (engine/impact_pass.py); see impacts_on
    targets: tuple = ()  # with impacts: the vehicles (scene indices) whose bodies stones hit
    spin: bool = False  # each rock's angular velocity and orientation (engine/tumble.py); see spin_on
    drawn: bool = False  # a mirror of each rock's drawn state for Simulation.changes() (engine/changes.py)
    effects: tuple = ()  # the optional effects that run (config/effects/: their names; engine/effects/)

    @classmethod
    def from_scene(cls, scene, tumble: bool = False, changes: bool = True) -> "Plan":
        """The plan of ``scene``; ``tumble``: the caller draws or exports the rocks' orientations (spin_on);
        ``changes``: the caller reads what changed (``Simulation.changes()``), so the World keeps its mirror."""
        fx, sim = scene.effects, scene.sim
        n = scene.bed.rocks
        splash = bool(fx.splash and any(v.splash for v in scene.vehicles) and n > 0)
        center = sim.hash.insert == "center"
        scope_all = sim.hash.scope == "all"
        return cls(splash=splash, flight=splash, recycle=bool(fx.recycle and n > 0), center=center,
                   scope_all=scope_all,
                   swept=sim.detection in ("swept", "patch"), patch=sim.detection == "patch",
                   throw=scene.launch.model, fenders=bool(fx.fenders and scene.launch.model == "tread"),
                   substeps=int(sim.substeps) if sim.detection == "ray" else 1,
                   reorder_every=(int(sim.hash.reorder_every) if (splash and center and scope_all
                                                                   and sim.stepping == "full") else 0),
                   integrator=sim.integrator, gravity=bool(fx.gravity), drag=fx.drag, ground=fx.ground,
                   cell_size=cell_size(scene), active=sim.stepping == "active" and n > 0,
                   impacts=impacts_on(scene, splash), targets=impact_targets(scene, splash),
                   spin=spin_on(scene, tumble), drawn=bool(changes and n > 0), effects=effects_on(scene))

    def passes(self) -> list[str]:
        out = []
        if self.flight:
            out.append(f"flight ({self.integrator}, gravity {'on' if self.gravity else 'off'}, "
                       f"drag {self.drag}, ground {self.ground})")
        if self.spin:
            out.append("tumble (spin and orientation)")
        if self.recycle:
            out.append("recycle")
        if self.splash:
            out.append(f"hash build ({'centre' if self.center else 'aabb'} insert, cell {self.cell_size:g} m, "
                       f"{'every rock' if self.scope_all else 'rocks near tires'})")
            how = "patch" if self.patch else ("swept" if self.swept else f"ray x{self.substeps}")
            throw = self.throw + (" model, fenders" if self.fenders else " model")
            out.append(f"tire pass ({how}, {throw})")
        if self.impacts:
            out.append(f"impacts (stones against {len(self.targets)} "
                       f"bod{'y' if len(self.targets) == 1 else 'ies'}, swept; events)")
        out += [f"{name} (optional effect)" for name in self.effects]
        return out


def impacts_on(scene, splash: bool) -> bool:
    """Impacts run when the scene asks for them, rocks fly, and some vehicle with ``hit`` can be reached by the
    stones of another one that splashes (a thrower's own body is left to its fenders and mud flaps)."""
    if not (scene.effects.impacts and splash):
        return False
    throwers = [i for i, v in enumerate(scene.vehicles) if v.splash]
    return any(v.hit and any(t != i for t in throwers) for i, v in enumerate(scene.vehicles))


def impact_targets(scene, splash: bool) -> tuple:
    """The vehicles stones can hit when impacts run (those with ``hit``), in scene order; () otherwise."""
    if not impacts_on(scene, splash):
        return ()
    return tuple(i for i, v in enumerate(scene.vehicles) if v.hit)


def spin_on(scene, tumble: bool) -> bool:
    """Spin and orientation are tracked when the caller asks for them (``tumble``: render, view and export draw
    or export them) or the scene does for every command (``[effects] tumble = "always"``), and there are rocks.
    Otherwise they are neither allocated nor compiled: a headless simulate pays nothing for them."""
    return bool((tumble or scene.effects.tumble == "always") and scene.bed.rocks > 0)


def cell_size(scene) -> float:
    """The hash cell edge in metres: "auto" is 2 r_max for centre insert (one cell per rock, queries dilated
    by one cell) and r_min for AABB insert (the original design)."""
    r_min, r_max = scene.bed.rock_radius
    cs = scene.sim.hash.cell_size
    if cs == "auto":
        return 2.0 * r_max if scene.sim.hash.insert == "center" else r_min
    if cs == "min_radius":
        return r_min
    if cs == "max_diameter":
        return 2.0 * r_max
    return float(cs)
