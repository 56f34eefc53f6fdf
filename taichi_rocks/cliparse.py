"""The command line's grammar: ``parser`` (every command of ``taichi-rocks`` and its options, cli.py runs them)
and the argument types it and the tools' command lines share (tools/compare_runs.py, tools/nudge.py): each
refuses a bad value with one line, as argparse reports it (exit status 2).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def whole(minimum: int, expected: str = "a whole number", bound: str | None = None):
    """An argument type: an integer >= ``minimum`` (``bound``: how the refusal says it; default ">= minimum")."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be {bound or f'>= {minimum}'}, got {value}")
        return value
    return parse


def finite(expected: str, must: str, ok):
    """An argument type: a finite float for which ``ok(value)`` holds (``must``: the refusal's words)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if not (math.isfinite(value) and ok(value)):
            raise argparse.ArgumentTypeError(f"must be {must}, got {text}")
        return value
    return parse


positive_int = whole(1, "a positive integer", "> 0")
positive_float = finite("a number", "a finite number > 0", lambda v: v > 0)
distance = finite("a distance in metres", "a finite distance >= 0", lambda v: v >= 0)


def resolution(text: str) -> tuple[int, int]:
    """An argument type: WIDTHxHEIGHT (config/resolution.py)."""
    from .config.resolution import parse_resolution

    try:
        return parse_resolution(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def parser(description: str) -> argparse.ArgumentParser:
    """The command line's parser: every command and its options (docs/cli.md is generated from it)."""
    from .runner.tasks import BACKENDS
    from .config.arches import ARCHES
    from .output.formats import FORMATS

    p = argparse.ArgumentParser(prog="taichi-rocks", description=description)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    c = sub.add_parser("check", help="validate scene files (and recorded drives) and summarise what will run")
    c.add_argument("scenes", nargs="+", metavar="SCENE", help="a scene file, or a recorded drive (docs/drives.md)")

    sub.add_parser("schema", help="print the JSON Schema of scene files")

    def engine_args(q):
        q.add_argument("scene", metavar="SCENE")
        q.add_argument("--frames", type=positive_int, help="frames to produce (default: duration x fps)")
        q.add_argument("--fps", type=positive_float, help="frames per second (default: [render] fps)")
        q.add_argument("--arch", choices=ARCHES, default="cpu", help="Taichi backend (gpu falls back to cpu)")
        q.add_argument("--seed", type=int, help="override the scene's seed")
        q.add_argument("--overwrite", action="store_true", help="replace existing outputs")

    def selection_args(q, only_default, only_help):
        q.add_argument("--only", choices=("flying", "all"), default=None,
                       help=f"{only_help} (default: {only_default})")
        q.add_argument("--crop", type=positive_float, metavar="RADIUS",
                       help="keep only the rocks within RADIUS m of the camera's followed vehicle")

    s = sub.add_parser("simulate", help="run headless and write an .npz of the rock states")
    engine_args(s)
    s.add_argument("--out", type=str, help="output .npz (default: renders/<scene>/<scene>.npz)")
    s.add_argument("--layout", choices=("light", "full"), default="light",
                   help="light: rows of the rocks that changed, relative to the floating origin; full: every "
                        "rock of every frame, float64 world (default: light; taichi_rocks.load_run reads both)")
    selection_args(s, "flying", "light layout: write the rocks that changed (flying; the others are unchanged) "
                                "or every rock every frame (all)")
    s.add_argument("--impacts", type=str, metavar="FILE.csv",
                   help="with [effects] impacts: also write the impact events as CSV (the run file holds them)")

    e = sub.add_parser("export", help="write the run for other tools: USD (Houdini, Omniverse, Unreal, Blender) "
                                      "or PLY point files")
    engine_args(e)
    e.add_argument("--format", choices=tuple(FORMATS), default=next(iter(FORMATS)))
    e.add_argument("--out", type=str, help="FILE.usdc, or a folder for ply (default: renders/<scene>/<scene>.usdc "
                                            "or renders/<scene>/ply/)")
    selection_args(e, "all", "flying: only the rocks in the air or that moved this frame; all: every rock")

    r = sub.add_parser("render", help="render frames (PNG) and a video with the offscreen GGUI renderer")
    engine_args(r)
    r.add_argument("--out", type=str, help="output folder (default: renders/<scene>/)")
    r.add_argument("--resolution", type=resolution, help="WIDTHxHEIGHT, even (default: [render])")
    r.add_argument("--format", choices=("mp4", "gif", "png"), default="mp4")
    r.add_argument("--profile", action="store_true",
                   help="report the seconds of each stage of the frame, and write them to OUT/profile.json")
    r.add_argument("--resume", action="store_true", help="continue an interrupted render")
    r.add_argument("--checkpoint-every", type=positive_int, default=30, metavar="N",
                   help="save the simulation state every N frames, for --resume (default: 30)")

    _view_parser(sub, ARCHES)

    a = sub.add_parser("aot", help="write the scene's step as an ahead-of-time module for a host without Python "
                                   "(native/, docs/native.md)")
    a.add_argument("scene", metavar="SCENE")
    a.add_argument("--arch", choices=("x64", "vulkan"), default="x64",
                   help="the backend the module runs on: x64 (the CPU) or vulkan (default: x64)")
    a.add_argument("--out", type=str, required=True, metavar="DIR", help="the module's folder")
    a.add_argument("--seed", type=int, help="override the scene's seed")
    a.add_argument("--tumble", action="store_true", help="track the rocks' orientations (changes() gives them)")
    a.add_argument("--overwrite", action="store_true", help="replace an existing DIR")
    _bench_parser(sub, ARCHES, BACKENDS)
    _sweep_parser(sub, ARCHES, BACKENDS)
    return p


def _view_parser(sub, arches) -> None:
    v = sub.add_parser("view", help="the simulation in a window: look, scrub and tweak (keys: docs/rendering.md)")
    v.add_argument("scene", metavar="SCENE")
    v.add_argument("--arch", choices=arches, default="cpu", help="Taichi backend (gpu falls back to cpu)")
    v.add_argument("--seed", type=int, help="override the scene's seed")
    v.add_argument("--resolution", type=resolution, help="WIDTHxHEIGHT, even (default: [render])")
    v.add_argument("--record", type=Path, metavar="DIR", help="write every frame shown (panel included) as "
                                                               "DIR/frame_00000.png ...")
    v.add_argument("--overwrite", action="store_true", help="replace the frames in a --record DIR and an existing "
                                                            "--record-drive FILE")
    v.add_argument("--drive", metavar="NAME", help="drive vehicle NAME with W/S/A/D (a scripted one starts where its "
                                                    "path does); the camera follows it")
    v.add_argument("--record-drive", type=Path, metavar="FILE", help="with --drive: write the poses driven to FILE "
                                                                      "when the window closes (docs/drives.md), for "
                                                                      'a scene\'s path = { kind = "recorded" }')
    v.add_argument("--quit-after", type=positive_float, metavar="SECONDS",
                   help="close the window SECONDS after the first frame (automation, memory measurements)")


def _bench_parser(sub, arches, backends) -> None:
    b = sub.add_parser("bench", help="measure accuracy against cost and speed against peers")
    b.add_argument("--quick", action="store_true", help="a short smoke run (< 2 minutes)")
    b.add_argument("--out", type=Path, default=Path("renders/bench"))
    b.add_argument("--arch", choices=arches, default="cpu")
    b.add_argument("--only", choices=("launch", "activity", "impacts", "frame"),
                   help="run one study only: launch (what the tread throws), activity (cost against activity), "
                        "impacts (stones that hit the vehicle behind) or frame (the default scene in a 60 Hz game "
                        "loop)")
    b.add_argument("--overwrite", action="store_true", help="replace the results of an earlier run in --out")
    b.add_argument("--backend", choices=backends, help="where the activity study's processes run: here, "
                                                                "one at a time (default), or on a Ray cluster")
    b.add_argument("--address", metavar="ADDR", help="the Ray cluster to join (host:port; implies --backend ray)")


def _sweep_parser(sub, arches, backends) -> None:
    w = sub.add_parser("sweep", help="run every combination of a sweep file's grid, on local processes or a Ray "
                                     "cluster, into results.csv, sweep.json, runs/ and plots/")
    w.add_argument("sweep", metavar="SWEEP", help="the sweep file (TOML; docs/sweeps.md)")
    w.add_argument("--out", type=str, required=True, metavar="DIR", help="the results folder")
    w.add_argument("--backend", choices=backends, help="local processes (default) or a Ray cluster "
                                                                "(default with --address)")
    w.add_argument("--workers", type=positive_int, metavar="N", help="worker processes or actors (default: "
                                                                      "one per core, at most one per run)")
    w.add_argument("--threads", type=positive_int, metavar="T", help="Taichi threads per worker (default: "
                                                                      "cores / workers)")
    w.add_argument("--address", metavar="ADDR", help="join the Ray cluster at ADDR (host:port of `ray start "
                                                      "--head`); without it the ray backend starts a local one")
    w.add_argument("--arch", choices=arches, default="cpu", help="Taichi backend of the runs")
    w.add_argument("--resume", action="store_true", help="continue: run only the runs without a row in DIR")
    w.add_argument("--overwrite", action="store_true", help="replace the results in DIR")
    w.add_argument("--yes", action="store_true", help="run a sweep of more than 10000 runs (refused without it)")
