"""Command line: ``taichi-rocks check | schema | simulate | export | render | view | aot | bench | sweep``.

Exit status: 0 success; 1 the simulation went wrong (runtime guard; a sweep: a run failed); 2 bad input (scene, arguments,
existing outputs, missing Vulkan, no display for ``view``); 130 interrupted (Ctrl-C); 128 + N ended by signal N
(SIGTERM 143, SIGHUP 129), cleaned up as after a Ctrl-C. Errors are one line per problem on stderr, never a
traceback.
"""

from __future__ import annotations

import importlib
import json
import os
import signal
import sys
from pathlib import Path

from .cliparse import parser

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class UsageError(Exception):
    """Bad input that is not a scene problem; the message is one line."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM, SIGHUP: ``signum``), with what the user can do next (``hint``: the rest of the
    message's line)."""

    def __init__(self, hint: str = "", signum: int = signal.SIGINT):
        super().__init__()
        self.hint = hint
        self.signum = int(signum)


# Signals that end a run as Ctrl-C does: the same clean-up (every writer removes its temporaries on a
# KeyboardInterrupt), a line saying so, exit 128 + the signal's number.
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


def _raise_stop(signum, frame):
    raise Interrupted(signum=signum)


def _signal_name(signum: int) -> str:
    return signal.Signals(signum).name


def _err(msg: str) -> None:
    print(msg, file=sys.stderr)


def _check_arch(scene, arch: str) -> None:
    """Refuse, before anything is written or compiled, a scene that ``arch`` cannot run (f64 or aabb insertion
    on Vulkan: config/arches.py)."""
    from .config.arches import arch_problem
    from .config.scene import SceneError

    problem = arch_problem(scene, arch)
    if problem:
        raise SceneError([problem])


def cmd_check(args) -> int:
    from .config.drivefile import DriveFileError, is_drive_file, read_drive
    from .config.scene import SceneError, load_scene, summarise
    from .engine.layout import check_machine, estimate_memory

    status = EXIT_OK
    for i, path in enumerate(args.scenes):
        if is_drive_file(path):  # a recorded drive (docs/drives.md)
            try:
                rows = read_drive(path)
            except DriveFileError as e:
                _err(str(e))
                status = EXIT_USAGE
                continue
            print(("\n" if i else "") + f"drive {path}: {len(rows)} poses from t = {rows[0][0]:g} s to "
                  f"{rows[-1][0]:g} s")
            continue
        try:
            scene = load_scene(path)
            check_machine(scene)
        except SceneError as e:
            _err(str(e))
            status = EXIT_USAGE
            continue
        if i:
            print()
        print(summarise(scene, estimate_memory(scene)))
    return status


def cmd_schema(args) -> int:
    from .config.scene import scene_json_schema

    print(json.dumps(scene_json_schema(), indent=2))
    return EXIT_OK


def cmd_simulate(args) -> int:
    from .config.scene import load_scene

    scene = load_scene(args.scene)
    _check_arch(scene, args.arch)
    from .app.simulate import simulate_scene

    info = simulate_scene(scene, out=args.out, frames=args.frames, fps=args.fps, arch=args.arch, seed=args.seed,
                          overwrite=args.overwrite, layout=args.layout, only=args.only, crop=args.crop,
                          impacts=args.impacts)
    print(f"wrote {info['path']}: {info['frames']} frames of {info['rocks']} rocks, "
          f"{info['launches']} launches, {info['bytes'] / 1e6:.1f} MB")
    if "impacts" in info:
        from .output.runs import impacts_summary

        print(impacts_summary(info["impacts"], [v.name for v in scene.vehicles]))
        if info["impacts_dropped"]:
            print(f"warning: {info['impacts_dropped']} impact events dropped: more between two drains than "
                  f"[impacts] capacity holds", file=sys.stderr)
    if args.impacts is not None:
        print(f"wrote {args.impacts}: {len(info.get('impacts', ()))} impact events")
    return EXIT_OK


def cmd_export(args) -> int:
    from .config.scene import load_scene

    scene = load_scene(args.scene)
    _check_arch(scene, args.arch)
    from .app.export import export_scene

    info = export_scene(scene, out=args.out, fmt=args.format, frames=args.frames, fps=args.fps, arch=args.arch,
                        seed=args.seed, overwrite=args.overwrite, only=args.only, crop=args.crop)
    frames = info["frames"]
    print(f"wrote {info['path']}: {frames} frames, {info['rocks_mean']:.0f} rocks per frame on average "
          f"(at most {info['rocks_max']}), {info['bytes'] / 1e6:.1f} MB, "
          f"{info['bytes'] / 1e6 / max(frames, 1):.2f} MB per frame")
    return EXIT_OK


def cmd_render(args) -> int:
    from .config.scene import load_scene

    scene = load_scene(args.scene)
    _check_arch(scene, args.arch)
    from .app.render import render_dir, render_scene, resumable

    out_dir = render_dir(scene, args.out)
    kwargs = dict(out_dir=out_dir, frames=args.frames, resolution=args.resolution, fps=args.fps,
                  fmt=args.format, arch=args.arch, overwrite=args.overwrite, progress=None,
                  profile=args.profile, checkpoint_every=args.checkpoint_every)
    if args.seed is not None:
        from .config.scene import scene_with

        scene = scene_with(scene, {"seed": args.seed})
    if args.resume:
        kwargs["resume"] = True
    try:
        info = render_scene(scene, **kwargs)
    except KeyboardInterrupt as e:
        # render leaves saved states only beside finished frames: only then is there something to resume
        raise Interrupted("; run the same command with --resume to continue" if resumable(out_dir) else "",
                          signum=getattr(e, "signum", signal.SIGINT)) from None
    if info.get("replayed_from") is not None:
        how = (f"restored the state saved after frame {info['replayed_from'] - 1}" if info["replayed_from"]
               else "simulated from the start")
        print(f"resumed at frame {info['resumed_from']} ({how})")
    where = info.get("video") or info.get("frames_dir")
    if info.get("resumed_from", 0) >= info.get("frames", 0):
        print(f"wrote {where}: all {info.get('frames')} frames were already rendered")
    else:
        print(f"wrote {where}: {info.get('frames')} frames at {info.get('fps_measured', 0):.2f} frames/s")
    if args.profile and info.get("profile"):
        for k, v in info["profile"].items():
            print(f"  {k:<12} {v:8.2f} s")
    return EXIT_OK


def cmd_view(args) -> int:
    from .config.scene import load_scene, scene_with
    from .render.display import NO_DISPLAY_HINT, display_problem

    scene = load_scene(args.scene)
    if args.seed is not None:
        scene = scene_with(scene, {"seed": args.seed})
    _check_arch(scene, args.arch)
    from .engine.layout import frame_problem

    if frame_problem(scene, args.resolution):
        raise UsageError(frame_problem(scene, args.resolution))
    problem = display_problem()  # before Taichi starts: no window without a screen
    if problem:
        raise UsageError(f"{problem}: the window needs a screen; {NO_DISPLAY_HINT}")
    from .app.view import check_drive_file, check_record_dir, drive_scene, view_scene

    if args.record is not None:
        check_record_dir(args.record, args.overwrite)  # before the window opens
    if args.record_drive is not None and args.drive is None:
        raise UsageError("--record-drive needs --drive NAME (the vehicle whose drive is recorded)")
    if args.drive is not None:
        try:
            drive_scene(scene, args.drive)
        except ValueError as e:
            raise UsageError(str(e)) from None
    if args.record_drive is not None:
        check_drive_file(args.record_drive, args.overwrite)
    from .engine.runtime import init_taichi

    init_taichi(args.arch)
    info = view_scene(scene, arch=args.arch, resolution=args.resolution, record=args.record,
                      overwrite=args.overwrite, quit_after=args.quit_after, drive=args.drive,
                      record_drive=args.record_drive)
    shots = info["screenshots"]
    print(f"view: {info['frames_shown']} frames shown in {info['seconds']:.1f} s"
          + (f", {len(shots)} screenshot(s): {', '.join(shots)}" if shots else "")
          + (f", {info['recorded']} frames written to {args.record}" if args.record is not None else "")
          + (f", {info['driven']} poses of {args.drive} written to {args.record_drive}"
             if args.record_drive is not None else ""))
    return EXIT_OK


def cmd_aot(args) -> int:
    from .config.scene import load_scene, scene_with

    scene = load_scene(args.scene)
    if args.seed is not None:
        scene = scene_with(scene, {"seed": args.seed})
    from .app.aot import make_module

    info = make_module(scene, args.arch, args.out, overwrite=args.overwrite, tumble=args.tumble)
    print(f"wrote {info['path']}: {info['arch']} module of {info['kernels']} kernels, {info['rocks']} rocks, "
          f"drives of {info['steps']} steps, {info['bytes'] / 1e6:.1f} MB")
    return EXIT_OK


def cmd_bench(args) -> int:
    from .config.arches import NO_F64

    if args.arch in NO_F64 and args.only is None:  # before anything is written or compiled
        raise UsageError(f'--arch {args.arch}: the accuracy study runs simulations in sim.precision = "f64", which '
                         f"Taichi's {args.arch} backend cannot compile; use --arch cpu or cuda, or --only launch "
                         "or --only activity")

    backend = args.backend or ("ray" if args.address else "local")
    if args.address and backend != "ray":
        raise UsageError("--address is for --backend ray")
    where = dict(backend=backend, address=args.address)
    if args.only in ("launch", "impacts", "frame") and backend != "local":
        raise UsageError(f"the {args.only} study runs on this machine; --backend is for the activity study's processes")
    if args.only == "launch":
        from .bench.launch import run_launch_study
        info = run_launch_study(out_dir=args.out, quick=args.quick, arch=args.arch, progress=None,
                                overwrite=args.overwrite)
        print(f"wrote {info['report']}")
        return EXIT_OK
    if args.only == "impacts":
        from .bench.impacts import run_impacts_study
        info = run_impacts_study(out_dir=args.out, quick=args.quick, arch=args.arch, progress=None,
                                 overwrite=args.overwrite)
        print(f"wrote {info['report']}")
        return EXIT_OK
    if args.only == "frame":
        from .bench.frame import run_frame_study
        info = run_frame_study(out_dir=args.out, quick=args.quick, arch=args.arch, progress=None,
                               overwrite=args.overwrite)
        print(f"wrote {info['report']}")
        return EXIT_OK
    if args.only == "activity":
        from .bench.activity import run_activity_study
        info = run_activity_study(out_dir=args.out, quick=args.quick, arch=args.arch, progress=None,
                                  overwrite=args.overwrite, **where)
        print(f"wrote {info['report']}")
        return EXIT_OK
    from .bench.run import run_bench
    info = run_bench(out_dir=args.out, quick=args.quick, arch=args.arch, progress=None, overwrite=args.overwrite,
                     **where)
    print(f"wrote {info.get('report', args.out)}")
    return EXIT_OK


def cmd_sweep(args) -> int:
    from .app.sweep.sweep import run_sweep

    backend = args.backend or ("ray" if args.address else "local")
    if args.address and backend != "ray":
        raise UsageError("--address is for --backend ray")
    if args.resume and args.overwrite:
        raise UsageError("--resume and --overwrite exclude each other")
    try:
        rows = run_sweep(args.sweep, args.out, backend=backend, workers=args.workers, threads=args.threads,
                         address=args.address, resume=args.resume, overwrite=args.overwrite, arch=args.arch,
                         yes=args.yes, announce=lambda line: print(line, file=sys.stderr, flush=True))
    except ConnectionError as e:
        raise UsageError(f"cannot reach the Ray cluster at {args.address}: {str(e).splitlines()[0]} (a cluster "
                         f"with token authentication needs RAY_AUTH_MODE=token here too)") from None
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"wrote {args.out / 'results.csv'}: {len(rows)} runs, {len(failed)} failed"
          + (f" ({', '.join(r['id'] for r in failed[:8])}{' ...' if len(failed) > 8 else ''})" if failed else ""))
    return EXIT_FAILED if failed else EXIT_OK


# What each command imports, loaded up front while Ctrl-C is held back (see main). The second group: what the
# libraries import on first use (NumPy's memmap, tqdm's lock, Taichi's first kernel compilation, the ffmpeg
# binary's lookup); a Ctrl-C that lands in such a late first import can be swallowed (CPython reports it as
# "Exception ignored in: <function _get_module_lock.<locals>.cb ...>" and the run goes on). Imported if present.
_PRELOAD = {
    "check": ("taichi_rocks.config.scene", "taichi_rocks.engine.layout"),
    "schema": ("taichi_rocks.config.scene",),
    "simulate": ("taichi_rocks.config.scene", "taichi_rocks.engine.simulation", "taichi_rocks.app.simulate", "tqdm"),
    "export": ("taichi_rocks.config.scene", "taichi_rocks.engine.simulation", "taichi_rocks.app.export", "tqdm"),
    "render": ("taichi_rocks.config.scene", "taichi_rocks.engine.simulation", "taichi_rocks.app.render", "taichi_rocks.output.video",
               "taichi_rocks.output.resume", "tqdm", "imageio.v3", "imageio.plugins.ffmpeg", "imageio_ffmpeg",
               "imageio.plugins.pillow", "PIL.Image"),  # pillow: a dependency of imageio
    "view": ("taichi_rocks.config.scene", "taichi_rocks.render.display"),  # the rest once a display is found
    "bench": ("taichi_rocks.config.scene", "taichi_rocks.engine.simulation", "taichi_rocks.bench.run",
              "taichi_rocks.bench.launch", "taichi_rocks.bench.activity", "taichi_rocks.bench.impacts"),
    "sweep": ("taichi_rocks.config.sweep", "taichi_rocks.app.sweep.sweep", "tqdm"),
    "aot": ("taichi_rocks.config.scene", "taichi_rocks.engine.simulation", "taichi_rocks.app.aot"),
}
_LATE = ("mmap", "multiprocessing.synchronize", "taichi.lang.matrix_ops")
_PRELOAD_IF_PRESENT = {"simulate": _LATE, "bench": _LATE, "sweep": ("multiprocessing.connection",),
                       "render": _LATE + (
    "imageio_ffmpeg.binaries", "importlib.readers", "importlib.resources.readers"),
    "export": _LATE + ("pxr.Usd", "pxr.UsdGeom", "pxr.Vt", "pxr.Gf", "pxr.Sdf", "pxr.Tf")}
# Pillow imports its ~50 format plugins on the first lookup of a file name's extension, which imageio makes when
# a render assembles its GIF at the end and when --resume reads the kept frames back: done at start-up instead.
_PRELOAD_CALLS = {"render": (("PIL.Image", "init"),)}


# The commands that start Taichi here or in their workers, and whether TAICHI_ROCKS_THREADS counts for them (a
# sweep's workers get theirs from --threads): their environment variables (config/environment.py) are checked
# before anything starts.
_ENVIRONMENT = {"simulate": True, "export": True, "render": True, "bench": True, "view": True, "sweep": False,
                "aot": True}


def _start(argv):
    """Parse the arguments, import what the command needs and start Taichi (main holds Ctrl-C back meanwhile).

    A KeyboardInterrupt raised inside a third-party import can be swallowed there (the run then goes on as if
    nothing happened) or leave a half-initialised extension module behind (seen: Ctrl-C during SciPy's import
    ended in 'ImportError: generic_type: type "ObjSense" is already registered!'); Taichi's initialisation
    is held back too. Nothing is written before this returns."""
    args = parser(__doc__.split("\n")[0]).parse_args(argv)
    for name in _PRELOAD[args.command]:
        importlib.import_module(name)
    for name in _PRELOAD_IF_PRESENT.get(args.command, ()):
        try:
            importlib.import_module(name)
        except ImportError:
            pass
    if args.command == "export":
        from .output.formats import writer_class

        writer_class(args.format)  # the format's module and the libraries it needs (usd-core for usd)
    for module, function in _PRELOAD_CALLS.get(args.command, ()):
        getattr(importlib.import_module(module), function)()
    if args.command in _ENVIRONMENT:
        from .config.environment import environment_problem

        problem = environment_problem(threads=_ENVIRONMENT[args.command])
        if problem:
            raise UsageError(f"taichi-rocks {args.command}: {problem}")
    if args.command in ("simulate", "export", "render", "bench"):
        from .engine.runtime import init_taichi

        init_taichi(args.arch)
    if args.command == "aot":  # the Simulation whose World the module starts from runs on the module's backend
        from .engine.runtime import init_taichi

        init_taichi("cpu" if args.arch == "x64" else args.arch, warn=lambda msg: None)
    return args


def main(argv=None, *, held=None, restore=None) -> int:
    """The command line. ``held``: Ctrl-C presses (and SIGTERM, SIGHUP) already held back (``python -m
    taichi_rocks`` holds them from its first line); ``restore``: the SIGINT handler to put back after start-up
    (default: the one found). SIGTERM and SIGHUP end the command as Ctrl-C does (module docstring); their
    handlers found are put back when it returns."""
    held = [] if held is None else held
    if restore is None:
        restore = signal.getsignal(signal.SIGINT)
        if not callable(restore) and restore not in (signal.SIG_IGN, signal.SIG_DFL):
            restore = signal.default_int_handler
    before = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    for s in (signal.SIGINT, *STOP_SIGNALS):
        signal.signal(s, lambda signum, frame: held.append(signum))
    try:
        try:
            args = _start(argv)
        except UsageError as e:  # a bad environment variable: one line, before anything started
            _err(str(e))
            return EXIT_USAGE
        finally:
            signal.signal(signal.SIGINT, restore)
            for s in STOP_SIGNALS:
                signal.signal(s, _raise_stop)
        return _run(args, held)
    finally:
        for s, h in before.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


_OUT_EXPECTED = {"simulate": "an .npz file name", "render": "a folder name", "sweep": "a folder name",
                 "aot": "a folder name"}


def _check_out(args) -> None:
    """``--out`` (and ``--impacts``) given as an empty name: refused, saying what was expected (an empty path
    would otherwise mean the current folder)."""
    for flag in ("out", "impacts"):
        value = getattr(args, flag, None)
        if value is not None and str(value).strip() == "":
            expected = ("a .csv file name" if flag == "impacts" else _OUT_EXPECTED.get(args.command) or
                        ("a folder name" if getattr(args, "format", "") == "ply" else "a .usdc file name"))
            raise UsageError(f"--{flag}: an empty name, expected {expected}")
        if value is not None:
            setattr(args, flag, Path(value))


def _run(args, held) -> int:
    from .config.scene import SceneError

    handler = {"check": cmd_check, "schema": cmd_schema, "simulate": cmd_simulate, "export": cmd_export,
               "render": cmd_render, "view": cmd_view, "aot": cmd_aot, "bench": cmd_bench,
               "sweep": cmd_sweep}[args.command]
    try:
        if held:
            raise Interrupted(signum=held[-1])
        if args.command in ("simulate", "export", "render", "sweep", "aot"):
            _check_out(args)
        return handler(args)
    except SceneError as e:
        _err(str(e))
        return EXIT_USAGE
    except (UsageError, FileExistsError, ValueError) as e:
        _err(f"taichi-rocks {args.command}: {e}")
        return EXIT_USAGE
    except KeyboardInterrupt as e:
        signum = getattr(e, "signum", signal.SIGINT)
        if signum == signal.SIGINT:
            _err(f"taichi-rocks {args.command}: interrupted{getattr(e, 'hint', '')}")
            return EXIT_INTERRUPTED
        _err(f"taichi-rocks {args.command}: interrupted by {_signal_name(signum)}, temporaries removed"
             f"{getattr(e, 'hint', '')}")
        return 128 + int(signum)
    except Exception as e:  # noqa: BLE001 - one line, no traceback, for anything the engine raises
        if isinstance(e, OSError) and e.filename is not None and e.strerror:  # a write that failed (a full disk)
            _err(f"taichi-rocks {args.command}: {e.filename}: {e.strerror}")
            return EXIT_FAILED
        from .engine.simulation import HealthError

        if isinstance(e, HealthError):
            _err(f"taichi-rocks {args.command}: simulation failed at {e}")
            return EXIT_FAILED
        if "Vulkan" in str(e):
            _err(f"taichi-rocks {args.command}: {e}")
            return EXIT_USAGE
        if os.environ.get("TAICHI_ROCKS_DEBUG"):
            raise
        _err(f"taichi-rocks {args.command}: {type(e).__name__}: {e} (set TAICHI_ROCKS_DEBUG=1 for details)")
        return EXIT_FAILED
