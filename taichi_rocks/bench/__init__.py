"""``taichi-rocks bench``: the measured accuracy-against-cost study, speed against peers, and its report.

``run_bench(out_dir, quick, arch, progress)`` (bench/run.py) writes ``report.md``, ``results.json`` and six PNG
plots to ``out_dir`` and returns the results as a dict (with ``report`` = the report's path).

1. Accuracy against cost: integrator x dt against closed forms (flight.py), detection recall x vehicle speed
   against an analytic sweep (detection.py), precision x distance from the origin (precision.py), hash
   settings that must launch identical rocks (hashing.py).
2. Speed against peers: the full step for N rocks x T rear tires, per pass, against NumPy brute force, SciPy
   cKDTree, NVIDIA Warp HashGrid and a streaming floor (speed.py, peers.py).
3. Targets met or not (targets.py) and proposed presets (presets.py); report.py and plots.py write them up.

The benchmark drives the engine only through its public face: Simulation steps, the timing hook
(engine/timing.py PassTimer) for passes inside a step, engine/probes.py for passes on their own and for
flying test rocks, and new Simulations built from changed Scenes (on the same, pooled fields) for changed
settings. ``run_bench`` is ``taichi_rocks.run_bench`` (imported on first use) and
``taichi_rocks.bench.run.run_bench``; this package itself imports nothing, so that its light modules
(config.py) and the activity study's worker processes load only what they use.
"""
