"""Sweep files: a base scene, a grid of scene keys, seeds and what to measure (docs/sweeps.md).

    scene = "../scenes/minimal.toml"     # the base scene, relative to the sweep file
    seeds = [1, 2, 3]                    # optional: default the base scene's seed
    duration = 2.0                       # optional: overrides the scene's
    [grid]                               # every combination; keys are the scene's dotted paths
    "launch.grip" = [1e5, 2e5, 4e5]
    [measure]
    metrics = ["launch", "timing", "digest"]

A run is one combination of the grid's values with one seed: the base scene with those keys set
(:func:`~taichi_rocks.config.scene.scene_with`), validated like a scene file. Every grid value, and every
combination, is checked before anything runs; a problem is a :class:`SweepError` (a SceneError, so the command
line reports it with exit status 2), one line each: ``SWEEP: grid."launch.grip" = -1: must be >= 0, got -1``.
Which metrics exist is the sweep runner's registry: :func:`load_sweep` takes their names. No Taichi here.
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, Strict, ValidationError

from .scene import Scene, SceneError, load_scene, scene_to_dict, scene_with
from .tomltext import read_toml
from .values import SEED_MAX, _show

__all__ = ["Sweep", "SweepError", "SweepRun", "load_sweep", "parse_sweep", "sweep_runs", "sweep_size"]


class SweepError(SceneError):
    """A sweep file that cannot be used; one ``SWEEP: key: what, got X`` line per problem."""


class _Table(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class Measure(_Table):
    """What each run reports: one or more metric names (the runner's registry)."""
    metrics: tuple[Annotated[str, Strict()], ...] = Field(("launch", "timing", "digest"), min_length=1,
                                                          description="metric names")


class Sweep(_Table):
    """A sweep: the base scene, seeds, an optional duration, the grid and the metrics."""
    scene: Annotated[str, Strict()] = Field(description="the base scene file, relative to the sweep file")
    seeds: Optional[tuple[Annotated[int, Strict(), Field(ge=0, le=SEED_MAX)], ...]] = Field(
        None, min_length=1, description="seeds of every combination (default: the base scene's)")
    duration: Optional[Annotated[float, Field(gt=0)]] = Field(None, description="s simulated per run")
    grid: dict[str, tuple[Any, ...]] = Field(description="scene key -> the values it takes", min_length=1)
    measure: Measure = Measure()


@dataclass(frozen=True)
class SweepRun:
    """One run: its id, grid values, seed and the scene to simulate (validated)."""
    id: str
    values: dict
    seed: int
    scene: Scene


def _key(loc: tuple) -> str:
    out = ""
    for x in loc:
        if isinstance(x, int):
            out += f"[{x}]"
        elif x not in ("tuple[int,...]", "none"):   # pydantic's labels of the Optional's members
            out += ("." if out else "") + (json.dumps(x) if "." in str(x) else str(x))
    return out


def _problems(err: ValidationError) -> list[str]:
    """pydantic's errors as ``key: what, got X`` (the grid keys quoted when dotted)."""
    fields = {"": list(Sweep.model_fields), "measure": list(Measure.model_fields)}
    out = []
    for e in err.errors():
        loc, kind, got = tuple(e["loc"]), e["type"], f", got {_show(e.get('input'))}"
        if kind == "extra_forbidden":
            choices = fields.get(_key(loc[:-1]), [])
            close = difflib.get_close_matches(str(loc[-1]), choices, n=1)
            out.append(f"{_key(loc)}: unknown key" + (f', did you mean "{close[0]}"?' if close else
                                                      " (expected one of " + ", ".join(choices) + ")"))
        elif kind == "missing":
            out.append(f"{_key(loc)}: required key is missing")
        elif kind in ("tuple_type", "list_type"):
            out.append(f"{_key(loc)}: expected a list{' of values' if loc[:1] == ('grid',) else ''}{got}")
        elif kind == "too_short" and isinstance(e.get("input"), (list, tuple, dict)) and e["input"]:
            continue  # pydantic adds it after an item failed; the item's own error says what is wrong
        elif kind == "none_required":
            continue  # the Optional's other member
        elif kind in ("greater_than", "greater_than_equal"):
            ctx = e.get("ctx") or {}
            out.append(f"{_key(loc)}: must be {'>' if kind == 'greater_than' else '>='} "
                       f"{_show(ctx.get('gt', ctx.get('ge')))}{got}")
        elif kind == "too_short":
            what = "at least one key" if loc == ("grid",) else "at least one value"
            out.append(f"{_key(loc)}: expected {what}{got}")
        else:
            out.append(f"{_key(loc)}: {e['msg'][:1].lower()}{e['msg'][1:]}{got}")
    return out


def parse_sweep(data: dict, source: str, metrics=None) -> Sweep:
    """Validate a sweep given as parsed TOML (the grid's own values are checked by :func:`sweep_runs`)."""
    if not isinstance(data, dict):
        raise SweepError([f"{source}: expected a table, got {_show(data)}"])
    try:
        sweep = Sweep.model_validate(data)
    except ValidationError as e:
        raise SweepError([f"{source}: {p}" for p in _problems(e)]) from None
    problems = [f"{source}: grid.{json.dumps(k)}: expected at least one value, got []"
                for k, vals in sweep.grid.items() if not vals]
    for name in sweep.measure.metrics if metrics is not None else ():
        if name not in metrics:
            close = difflib.get_close_matches(name, list(metrics), n=1)
            problems.append(f"{source}: measure.metrics: unknown metric {json.dumps(name)}"
                            + (f', did you mean "{close[0]}"?' if close else "")
                            + " (expected one of " + ", ".join(f'"{m}"' for m in metrics) + ")")
    if problems:
        raise SweepError(problems)
    return sweep


def load_sweep(path: Union[str, os.PathLike], metrics=None) -> tuple[Sweep, Scene]:
    """Read and validate a sweep file and its base scene; ``metrics``: the names allowed in [measure]."""
    source = str(path)
    data = read_toml(path, "sweep", SweepError)
    sweep = parse_sweep(data, source, metrics)
    scene_path = Path(path).parent / sweep.scene
    if not scene_path.is_file():
        raise SweepError([f"{source}: scene: no such scene file {json.dumps(sweep.scene)} "
                          f"(looked for {scene_path})"])
    try:
        base = load_scene(scene_path)
    except SceneError as e:
        raise SweepError([f"{source}: scene {json.dumps(sweep.scene)}: {p}" for p in e.problems]) from None
    return sweep, base


def _reason(e: SceneError, scene: Scene) -> str:
    """A scene problem without its ``FILE: key.path:`` prefix (the sweep line names the key itself)."""
    line = e.problems[0]
    head = f"{scene.source}: "
    line = line[len(head):] if line.startswith(head) else line
    return line.split(": ", 1)[1] if ": " in line else line


def sweep_size(sweep: Sweep) -> int:
    """The number of runs: the product of the grid's value counts, times the seeds (none built)."""
    n = len(sweep.seeds) if sweep.seeds is not None else 1
    for values in sweep.grid.values():
        n *= len(values)
    return n


def sweep_runs(sweep: Sweep, base: Scene, source: str, checked=None) -> list[SweepRun]:
    """Every run of the sweep (grid combinations in file order, the last key fastest, then seeds), each
    scene validated (once per combination: the seeds are in range by the Sweep model); SweepError naming the
    key and the value of every value or combination refused. ``checked()``: called once every value passed
    its own check, before the combinations are built (the slow part)."""
    fixed = {"duration": sweep.duration} if sweep.duration is not None else {}
    problems = []
    for key, values in sweep.grid.items():
        if key == "seed":
            problems.append(f"{source}: grid.seed: seeds are swept by seeds = [...], not by the grid")
            continue
        for v in values:  # the first value refused names the key (a bad key refuses them all alike)
            try:
                scene_with(base, {key: v, **fixed})
            except SceneError as e:
                problems.append(f"{source}: grid.{json.dumps(key)} = {_show(v)}: {_reason(e, base)}")
                break
    if problems:
        raise SweepError(problems)
    if checked is not None:
        checked()
    keys = list(sweep.grid)
    seeds = sweep.seeds if sweep.seeds is not None else (base.seed,)
    runs = []
    for combo in itertools.product(*(sweep.grid[k] for k in keys)):
        values = dict(zip(keys, combo))
        try:
            combined = scene_with(base, {**values, **fixed})
        except SceneError as e:
            shown = ", ".join(f"{json.dumps(k)} = {_show(v)}" for k, v in values.items())
            raise SweepError([f"{source}: grid: the combination {shown}: {_reason(e, base)}"]) from None
        for seed in seeds:
            scene = combined.model_copy(update={"seed": int(seed)})
            runs.append(SweepRun(f"r{len(runs):04d}", values, int(seed), scene))
    return runs


def sweep_fingerprint(sweep: Sweep, base: Scene) -> str:
    """SHA-256 of what decides the runs (the sweep and the base scene, every key): --resume checks it."""
    blob = json.dumps({"sweep": sweep.model_dump(mode="json"), "scene": scene_to_dict(base)}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()
