"""taichi_rocks: a bed of rocks that follows the player vehicle while the rear tires of vehicles
launch rocks into the air (Chen, Fu & Wegman 1999), simulated with Taichi and driven by TOML scenes.

The public API, imported lazily so that ``import taichi_rocks`` stays cheap (no Taichi, no SciPy)::

    from taichi_rocks import Simulation, load_scene, shipped_scene
    sim = Simulation(load_scene(shipped_scene("minimal")))  # or the path of any scene file
    sim.step(100)
    state = sim.state()

A run file written by ``taichi-rocks simulate`` (either layout) reads back as the full arrays with
``load_run("run.npz")["positions"]``.
"""

import importlib as _importlib
import os as _os

# Taichi prints a banner on stdout when imported; keep stdout for results (set before taichi is imported).
_os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")

__version__ = "0.1.0"

_API = {
    "Scene": "config.scene", "SceneError": "config.scene", "load_scene": "config.scene",
    "parse_scene": "config.scene", "scene_with": "config.scene", "shipped_scene": "config.scene",
    "Plan": "config.plan",
    "Simulation": "engine.simulation", "HealthError": "engine.simulation", "init_taichi": "engine.runtime",
    "record": "app.simulate", "load_run": "output.runs", "render_scene": "app.render",
    "Renderer": "render.renderer",
    "run_bench": "bench.run",
    "run_sweep": "app.sweep.sweep", "Sweep": "config.sweep", "SweepError": "config.sweep",
    "load_sweep": "config.sweep",
}
__all__ = sorted(_API)


def __getattr__(name: str):
    if name in _API:
        value = getattr(_importlib.import_module(f".{_API[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'taichi_rocks' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
