"""How sensitive a scene is to round-off: run it twice on the CPU, the second time with every rock moved by a
tiny step first, and count the rocks that end up apart.

    python tools/nudge.py scenes/convoy.toml --steps 300 --by 1e-6

Each rock moves by ``by`` metres along each axis, the sign drawn at random (seed 0): about what another backend's
rounding does to a position. A model with discrete choices (a tire hits a rock or misses it, a rock is inside
the bed or outside) turns a few such differences into different outcomes; this measures how many, as a floor for
comparing two backends (tools/compare_runs.py). It prints the rocks more than 1 mm and 1 m apart, the largest
distance and both runs' launch totals, and writes nothing. A scene that cannot be used, a ``--by`` that is not a
finite distance >= 0 and a ``--steps`` below 0 are one line and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from taichi_rocks.cliparse import distance, whole  # noqa: E402
from taichi_rocks.engine.runtime import init_taichi  # noqa: E402


def run(scene, steps: int, by: float) -> dict:
    """The states of ``scene`` (a Scene, or a scene file) after ``steps`` steps, as is and with every rock moved by
    ``by`` first."""
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.engine.simulation import Simulation

    scene = load_scene(scene) if isinstance(scene, (str, Path)) else scene
    out = {}
    for name, step in (("as is", 0.0), ("nudged", by)):
        sim = Simulation(scene)
        if step:
            st = sim.state()
            sign = np.sign(np.random.default_rng(0).standard_normal(st.positions.shape))
            sim.set_rocks(np.arange(sim.n_rocks), positions=st.positions + sign * step)
        sim.step(steps)
        out[name] = sim.state()
    return out


def summary(states: dict) -> dict:
    a, b = states["as is"], states["nudged"]
    d = np.linalg.norm(a.positions - b.positions, axis=1)
    return {"rocks": len(d), "over_1mm": int((d > 1e-3).sum()), "over_1m": int((d > 1.0).sum()),
            "max": float(d.max()) if len(d) else 0.0, "launches": (int(a.launches_total), int(b.launches_total))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--steps", type=whole(0, "a whole number of steps"), default=300)
    ap.add_argument("--by", type=distance, default=1e-6, help="metres each rock moves along each axis (default "
                                                              "1e-6)")
    args = ap.parse_args(argv)
    from taichi_rocks.config.scene import SceneError, load_scene

    try:
        scene = load_scene(args.scene)
        init_taichi("cpu")
    except (SceneError, ValueError) as e:
        print(str(e) if isinstance(e, SceneError) else f"nudge: {e}", file=sys.stderr)  # one line per problem
        return 2
    s = summary(run(scene, args.steps, args.by))
    print(f"{s['rocks']} rocks after {args.steps} steps, moved by {args.by:g} m first: {s['over_1mm']} more than "
          f"1 mm apart, {s['over_1m']} more than 1 m, at most {s['max']:.3g} m; launches {s['launches'][0]} and "
          f"{s['launches'][1]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
