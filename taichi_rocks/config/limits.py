"""Limits no sane run reaches, checked before anything runs: the steps a run would take (duration / dt, or
--frames / --fps over dt), and the runs of a sweep (more only with --yes, app/sweep/sweep.py). A scene of 2e12 steps (``sim.dt = 1e-12``) would run for years; it is refused with
the estimate, naming the key that makes it (config/models.py for the scene; app/frames.py for the flags)."""

from __future__ import annotations

__all__ = ["MAX_STEPS", "STEP_PACE_S", "MAX_SWEEP_RUNS", "steps_estimate", "duration_text"]

MAX_STEPS = 10**8  # steps of one run: 28 hours at 1 ms a step
STEP_PACE_S = 1e-4  # s per step of the smallest scenes on a fast machine: the estimate's optimistic pace
MAX_SWEEP_RUNS = 10_000  # runs of one sweep without --yes (validating them alone takes a few seconds)


def duration_text(seconds: float) -> str:
    """``seconds`` in the largest unit that fits: '6.34 years', '19.3 days', '12 s'."""
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("hours", 3600), ("minutes", 60)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


def steps_estimate(seconds: float, dt: float) -> str:
    """'2e+12 steps of 1e-12 s (about 6.34 years at 0.1 ms a step)': the steps of ``seconds`` of simulated time."""
    steps = seconds / dt
    return (f"{steps:.3g} steps of {dt:g} s (about {duration_text(steps * STEP_PACE_S)} at {STEP_PACE_S * 1e3:g} ms a "
            f"step), more than the {MAX_STEPS:.0e} a run may take")
