"""``taichi-rocks render``: simulate a scene and render it to PNG frames and a video: arguments, outputs,
resuming an interrupted render (output/resume.py), the frame loop and its profile. The drawing is
render/renderer.py's; the frames and the video are written by output/video.py."""

import json
import os
import sys
import time
from datetime import datetime
from pathlib import Path
from types import SimpleNamespace

from tqdm import tqdm

from ..bench.machine import loadavg, machine
from ..config.resolution import check_resolution
from ..config.scene import SceneError, load_scene
from ..engine.layout import frame_problem
from ..engine.runtime import init_taichi
from ..engine.simulation import Simulation
from ..output.atomic import check_place, new_folders, write_atomically
from ..output.resume import CHECKPOINT_EVERY, RenderCheckpoints, fingerprint, resume_dir
from ..output.video import FrameWriter, existing_size, finished_frames, frame_name, output_paths
from ..render.renderer import WINDOW_EVERY, Renderer, check_rocks
from ..render.stages import cpu_seconds
from .frames import check_steps

__all__ = ["render_scene", "render_dir", "resumable", "PROFILE_FILE"]

PROFILE_FILE = "profile.json"  # what --profile writes beside the frames (docs/results/render_profile.json)


def render_scene(scene_or_path, out_dir=None, frames=None, resolution=None, fps=None, fmt="mp4", arch="cpu",
                 overwrite=False, progress=True, profile=False, *, resume=False, rocks="splat",
                 window_every=WINDOW_EVERY, on_frame=None, checkpoint_every=None) -> dict:
    """Simulate a scene and render it offscreen to PNG frames plus an MP4 or GIF (``fmt="png"``: frames only).

    Args:
        scene_or_path: a scene file (TOML) or a validated Scene.
        out_dir: the output folder (default ``renders/<scene name>/``).
        frames: frames to draw (default: round(duration * fps)).
        resolution: (width, height), even, overriding ``[render] resolution``.
        fps: frames per second, overriding ``[render] fps``.
        fmt: "mp4", "gif" or "png" (frames only).
        arch: the Taichi backend (as for ``Simulation``).
        overwrite: replace existing outputs (else FileExistsError).
        progress: a tqdm bar on stderr (None: only on a terminal).
        profile: also return where the time went, and write it to ``out_dir``/profile.json.
        resume: continue an interrupted render in ``out_dir``.
        rocks: "splat" or "particles".
        window_every: frames between re-creations of the hidden window (0: never).
        on_frame: called as ``on_frame(k, image)`` with every frame drawn (tests).
        checkpoint_every: frames between saved simulation states, for ``resume`` (default 30).

    Returns:
        A summary dict (below).

    Raises:
        FileExistsError: outputs exist and ``overwrite`` is off.
        ValueError: an odd resolution, or a resume that does not match the interrupted render.
        RuntimeError: no Vulkan on this machine (the message names the packages to install).

    ``scene_or_path``: a scene file (TOML) or a validated :class:`~taichi_rocks.config.scene.Scene`. Frame k shows the
    simulation at t = k / fps; ``frames`` defaults to round(duration * fps). ``resolution`` and ``fps`` override
    the scene's [render] table. Outputs go to ``out_dir`` (default ``renders/<scene name>/``): ``frames/``
    and ``<scene name>.<fmt>``; existing outputs raise FileExistsError unless ``overwrite`` (which removes the
    old frames and video first). An odd resolution raises ValueError; a machine without Vulkan raises
    RuntimeError naming the packages to install. ``rocks``: "splat" (resting rocks drawn by a Taichi kernel
    behind the GGUI scene, flying ones as GGUI particles; fast) or "particles" (every rock a GGUI particle).
    ``resume``: keep the frames a previous (interrupted) render finished, frame_00000.png ... without a gap,
    restore the newest simulation state it saved before the first missing frame (every ``checkpoint_every``
    frames, default 30, in ``out_dir/.resume/``; see resume.py), advance the simulation and the camera from
    there to the first missing frame without drawing, re-encode the kept frames into the video and render the
    rest (the result equals an uninterrupted render: the simulation is deterministic); the frames must have
    the requested resolution, and the scene, fps and rock mode must be the interrupted render's.
    ``progress``: a tqdm bar on stderr; None shows it only on a terminal.
    ``on_frame(k, image)``, if given, sees every frame drawn (tests).

    Returns {"scene", "out_dir", "frames_dir", "video", "frames", "resumed_from" (first frame drawn),
    "replayed_from" (first frame simulated without drawing, after a restored state), "resolution", "video_fps",
    "seconds", "frames_per_second" (frames drawn / seconds of the frame loop; also "fps_measured"), "redraws"}
    and with ``profile`` a "profile" dict of seconds: "simulation", the frame's stages (render/stages.py
    STAGES: "camera", "culling" (the rock pass), "marks", "sky_ground", "declare" (GGUI's scene), "readback"
    (GGUI's drawing and its image handed back), "merge", "dust", "window"), "encoding" (time the render loop
    waited on the frame writer, including the final flush) and "encoding_busy" (the writer thread's own time,
    which overlaps the others), "other" (the rest of the frame loop), "setup"
    (before the first frame: scene, simulation and window set-up) and "first_frame" (the first frame alone,
    mostly kernel compilation; included in the others), and a "profile_cpu" dict of the process's CPU seconds in
    the simulation, the frame's stages and the whole loop (every thread's: steadier than wall time on a shared
    machine). With ``profile`` the render also writes them, with its machine and load, to ``out_dir``/PROFILE_FILE
    (profile.json, replaced if there)."""
    t_start = time.perf_counter()
    resolution = _check_arguments(resolution, fps, frames, rocks)
    job = _plan(scene_or_path, out_dir, frames, resolution, fps, fmt, overwrite, resume)
    job.arch, job.load_start, job.started = arch, loadavg(), datetime.now().strftime("%Y-%m-%d %H:%M:%S")
    run = _start(job, arch, resolution, rocks, window_every, checkpoint_every, resume)
    times = _draw(job, run, resume, progress, on_frame)
    times.start = t_start
    out = _report(job, run, times, profile)
    if profile:
        _write_profile(job, out)
    return out


def render_dir(scene, out_dir=None) -> Path:
    """The folder a render of ``scene`` writes to: ``out_dir``, by default ``renders/<scene name>/``."""
    return Path(out_dir) if out_dir is not None else Path("renders") / scene.name


def resumable(out_dir) -> bool:
    """True if a render into ``out_dir`` that ended early kept frames to resume from: it leaves its saved states
    (output/resume.py) only then, beside at least one finished frame."""
    return resume_dir(out_dir).is_dir() and finished_frames(output_paths(out_dir, "", "png")["frames"]) > 0


def _draw(job, run, resume, progress, on_frame) -> SimpleNamespace:
    """Open the outputs (checkpoints, frame writer), replay to the first frame to draw and draw the rest. The
    folders this creates are removed again if the render ends before its first finished frame (and then the
    saved states too: there is nothing to resume from)."""
    with new_folders(job.paths["frames"]):
        try:
            run.checkpoints.start(resume, job.start)
            run.writer = FrameWriter(job.out_dir, job.scene.name, job.video_fps, job.fmt, start=job.start,
                                     crf=job.scene.render.quality)
            t_replay = _replay(job, run)
            times = _frame_loop(job, run, progress, on_frame)
        except BaseException:
            run.renderer.close()
            if not finished_frames(job.paths["frames"]):
                run.checkpoints.finish()
            raise
    times.replay = t_replay
    return times


def _check_arguments(resolution, fps, frames, rocks):
    """ValueError on a bad argument; the resolution as (width, height) ints, or None."""
    if resolution is not None:
        resolution = check_resolution(resolution)
    if fps is not None and not (isinstance(fps, (int, float)) and fps > 0):
        raise ValueError(f"fps must be a number > 0, got {fps!r}")
    if frames is not None and (not isinstance(frames, int) or isinstance(frames, bool) or frames < 1):
        raise ValueError(f"frames must be an int >= 1, got {frames!r}")
    check_rocks(rocks)
    return resolution


def _existing_outputs(paths: dict) -> list:
    """Files of a previous render that this one would replace."""
    found = []
    video = paths["video"]
    if video is not None and video.exists():
        found.append(video)
    frames = paths["frames"]
    if frames.is_dir():
        found += sorted(frames.glob("frame_*.png"))
    return found


def _plan(scene_or_path, out_dir, frames, resolution, fps, fmt, overwrite, resume) -> SimpleNamespace:
    """What to render and where: the scene, the output paths, the frame count and rate, the first frame to
    draw (``start``: after the frames an interrupted render kept) and the old files to remove (``old``).
    Raises before anything is written."""
    scene = load_scene(scene_or_path) if isinstance(scene_or_path, (str, os.PathLike)) else scene_or_path
    out_dir = render_dir(scene, out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"{out_dir}: is a file, expected a folder for the render")
    check_place(out_dir, folder=True)
    paths = output_paths(out_dir, scene.name, fmt)  # ValueError on an unknown format
    video_fps = float(fps if fps is not None else scene.render.fps)
    n_frames = frames if frames is not None else max(1, int(round(scene.duration * video_fps)))
    check_steps(scene, n_frames, video_fps, frames, fps)
    problem = frame_problem(scene, resolution)
    if problem:
        raise (SceneError([problem]) if resolution is None else ValueError(problem))
    old = _existing_outputs(paths)
    start = 0
    if resume:
        start = min(finished_frames(paths["frames"]), n_frames)
        size = existing_size(paths["frames"]) if start else None
        want = resolution or tuple(int(x) for x in scene.render.resolution)
        if size is not None and tuple(size) != tuple(want):
            raise ValueError(f"cannot resume: {paths['frames']} holds {size[0]}x{size[1]} frames, "
                             f"this render is {want[0]}x{want[1]}")
        keep = {paths["frames"] / frame_name(i) for i in range(start)}
        old = [f for f in old if f not in keep]
    elif old and not overwrite:
        what = paths["video"] if paths["video"] in old else paths["frames"]
        raise FileExistsError(f"{what} already exists (pass overwrite=True or --overwrite to replace it)")
    return SimpleNamespace(scene=scene, out_dir=out_dir, paths=paths, fmt=fmt, video_fps=video_fps,
                           n_frames=n_frames, start=start, old=old)


def _start(job, arch, resolution, rocks, window_every, checkpoint_every, resume) -> SimpleNamespace:
    """Taichi, the simulation, the renderer (its window) and the checkpoints; the old outputs are removed only
    once all of these stand."""
    init_taichi(arch)
    # the flying rocks are drawn turned (render/tumbling.py); the renderer reads the rocks on the device, culled by
    # tiles (engine/drawing.py), not through changes(): no mirror to keep
    sim = Simulation(job.scene, arch=arch, tumble=True, track_changes=False)
    renderer = Renderer(sim, resolution=resolution, fps=job.video_fps, rocks=rocks, window_every=window_every)
    every = CHECKPOINT_EVERY if checkpoint_every is None else int(checkpoint_every)
    checkpoints = RenderCheckpoints(job.out_dir, fingerprint(job.scene, job.video_fps, renderer.resolution, rocks),
                                    every)
    if resume:
        try:
            checkpoints.check_same_render()
        except ValueError:
            renderer.close()
            raise
    for f in job.old:  # only now: a failure above leaves the previous render untouched
        f.unlink()
    return SimpleNamespace(sim=sim, renderer=renderer, checkpoints=checkpoints, writer=None, replay_from=0)


def _replay(job, run) -> float:
    """Resuming: restore the newest saved state, replay simulation and camera to the first frame to draw, draw
    nothing. Return the seconds it took. A run that records impacts replays from frame 0 instead: the
    windscreen marks of the frames before a saved state are not in it (render/hits.py takes them as it goes)."""
    t0 = time.perf_counter()
    try:
        if job.start:
            saved = None if run.sim.plan.impacts else run.checkpoints.latest_before(job.start)
            if saved is not None:
                run.replay_from = run.checkpoints.restore(saved, run.sim, run.renderer.rig) + 1
        for k in range(run.replay_from, job.start):
            run.sim.advance_to(k / job.video_fps)
            run.renderer.view()
            run.renderer.hits.update(run.sim)
    except BaseException:
        run.renderer.close()
        run.writer.close(ok=False)
        raise
    return time.perf_counter() - t0


def _frame_loop(job, run, progress, on_frame) -> SimpleNamespace:
    """Simulate, draw and write frames ``job.start`` ... ``job.n_frames - 1``; close the renderer and the writer
    (the video is finished only if every frame was written). Return the loop's timings."""
    sim, renderer, writer, checkpoints = run.sim, run.renderer, run.writer, run.checkpoints
    t = SimpleNamespace(sim=0.0, sim_cpu=0.0, first=0.0)
    ok = False
    bar = tqdm(total=job.n_frames, initial=job.start, unit="frame", desc=job.scene.name, file=sys.stderr,
               disable=None if progress is None else not progress, dynamic_ncols=True)
    t.loop_start, t.loop_cpu = time.perf_counter(), cpu_seconds()
    try:
        for k in range(job.start, job.n_frames):
            t0, c0 = time.perf_counter(), cpu_seconds()
            sim.advance_to(k / job.video_fps)
            t.sim += time.perf_counter() - t0
            t.sim_cpu += cpu_seconds() - c0
            img = renderer.render_frame()
            if on_frame is not None:
                on_frame(k, img)
            writer.write(img)
            if checkpoints.due(k, job.n_frames):
                checkpoints.save(k, sim, renderer.rig)
            bar.update(1)
            if k == job.start:
                t.first = time.perf_counter() - t.loop_start
        ok = True
    finally:
        bar.close()
        renderer.close()
        run.video = writer.close(ok=ok)
    t.loop_cpu = cpu_seconds() - t.loop_cpu
    checkpoints.finish()  # complete: nothing to resume
    return t


def _report(job, run, t, profile: bool) -> dict:
    """The dict render_scene returns (see there)."""
    seconds = time.perf_counter() - t.start
    loop = time.perf_counter() - t.loop_start
    renderer, video = run.renderer, run.video
    out = {
        "scene": job.scene.name,
        "out_dir": str(job.out_dir),
        "frames_dir": str(job.paths["frames"]),
        "video": str(video) if video is not None else None,
        "frames": job.n_frames,
        "resumed_from": job.start,
        "replayed_from": run.replay_from if job.start else None,
        "resolution": tuple(renderer.resolution),
        "video_fps": job.video_fps,
        "seconds": seconds,
        "frames_per_second": (job.n_frames - job.start) / loop if loop > 0 else 0.0,
        "redraws": renderer.redraws,  # frames whose GGUI layer had to be drawn twice (GGUI glitch guard)
    }
    out["fps_measured"] = out["frames_per_second"]
    if profile:
        writer = run.writer
        stages = renderer.stages.seconds
        prof = {"simulation": t.sim, **stages, "encoding": writer.timings["encode"],
                "encoding_busy": writer.timings["encode_busy"]}
        prof["other"] = max(0.0, loop - t.sim - sum(stages.values()) - prof["encoding"])
        prof["setup"] = t.loop_start - t.start - t.replay
        prof["resume_replay"] = t.replay  # simulating the frames kept from an interrupted render
        prof["first_frame"] = t.first  # included above; mostly kernel compilation (cached on later runs)
        out["profile"] = prof
        out["profile_cpu"] = {"simulation": t.sim_cpu, **renderer.stages.cpu, "loop": t.loop_cpu}
    return out


def _write_profile(job, out) -> None:
    """The profile of a render, with its machine and load, as JSON beside its frames (PROFILE_FILE): the run
    docs/rendering.md's table of the frame's stages is made from (docs/results/render_profile.json,
    tools/readme_tables.py)."""
    drawn = out["frames"] - out["resumed_from"]
    record = {"started": job.started, "scene": job.scene.name, "frames": drawn, "resolution": out["resolution"],
              "frames_per_second": out["frames_per_second"], "seconds": out["seconds"], "redraws": out["redraws"],
              "profile": out["profile"], "profile_cpu": out["profile_cpu"], "machine": machine(job.arch),
              "load_average_start": job.load_start, "load_average_end": loadavg()}
    data = (json.dumps(record, indent=1) + "\n").encode()
    write_atomically(job.out_dir / PROFILE_FILE, lambda f: f.write(data))
