"""The cost of the impacts pass: the step of the convoy scene at 1M rocks (4 vehicles, each splashing and hit)
with ``[effects] impacts`` on against off, full and active stepping, timed alternately in one process
(A/B/A/B, ``--rounds`` blocks of ``--steps`` steps each, after both ran to ``--warm`` s so that stones fly);
prints the median ms per step and the ratio. ``--compile``: instead, the first step's time (compiling the step's
kernels, Taichi's offline cache off) of a fresh process per case.

    python tools/impact_cost.py [--rocks 1000000] [--modes full active] [--compile]

Timings on a shared machine are noisy: compare only figures from one sitting.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np


def _scene(rocks: int, mode: str, impacts: bool):
    from taichi_rocks.config.scene import load_scene, scene_with

    sc = load_scene("scenes/convoy.toml")
    return scene_with(sc, {"bed.rocks": rocks, "sim.stepping": mode, "effects.impacts": impacts})


def _timed(sim, steps: int) -> float:
    import taichi as ti

    ti.sync()
    t = time.perf_counter()
    sim.step(steps)
    ti.sync()
    return (time.perf_counter() - t) / steps * 1e3


def step_cost(rocks: int, modes, rounds: int, steps: int, warm: float) -> dict:
    from taichi_rocks.engine.simulation import Simulation

    out = {}
    for mode in modes:
        sims = {on: Simulation(_scene(rocks, mode, on)) for on in (False, True)}
        for sim in sims.values():
            sim.advance_to(warm)
        times = {False: [], True: []}
        for _ in range(rounds):
            for on in (False, True):
                times[on].append(_timed(sims[on], steps))
        off, on = float(np.median(times[False])), float(np.median(times[True]))
        out[mode] = {"off_ms": off, "on_ms": on, "ratio": on / off, "events": len(sims[True].impacts()),
                     "in_air": sims[True].rocks_in_air()}
        del sims
    return out


def _first_step(rocks: int, mode: str, on: bool) -> float:
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(_scene(rocks, mode, on))
    t = time.perf_counter()
    sim.step(1)
    first = time.perf_counter() - t
    return first - _timed(sim, 5) / 1e3


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rocks", type=int, default=1_000_000)
    ap.add_argument("--modes", nargs="+", default=["full", "active"])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--warm", type=float, default=1.0)
    ap.add_argument("--compile", action="store_true")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)  # MODE on|off: a --compile child
    a = ap.parse_args()
    if a.one:
        print(json.dumps(_first_step(20000, a.one[0], a.one[1] == "on")))
        return 0
    if a.compile:
        env = dict(os.environ, TI_OFFLINE_CACHE="0")
        res = {}
        for mode in a.modes:
            for on in ("off", "on"):
                r = subprocess.run([sys.executable, __file__, "--one", mode, on], env=env, capture_output=True,
                                   text=True, check=True)
                res[f"{mode} {on}"] = float(r.stdout.strip().splitlines()[-1])
        print(json.dumps({k: round(v, 2) for k, v in res.items()}, indent=1))
        return 0
    print(json.dumps(step_cost(a.rocks, a.modes, a.rounds, a.steps, a.warm), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
