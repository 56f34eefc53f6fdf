"""Gravel: a Panda3D game with the rock system inside. Drive a car behind a truck on a gravel road; the truck's
rear tires throw the stones, they fly, tumble and land, and the ones that hit your car flash and chip or crack its
windscreen.

    python examples/panda3d_game.py                          # play, in a window (W/S/A/D or the arrows)
    python examples/panda3d_game.py --offscreen --frames 300 --out renders/game   # PNG frames, scripted driving

Needs Panda3D (``pip install .[game]``). Without a display it runs offscreen. Offscreen, the car follows a
recorded drive (examples/rockgame/follow.drive, or ``--drive FILE``) on a 60 Hz clock and Panda3D draws with its
software renderer. It prints its frame budget per part and, as its last line, one JSON object:
{"frames", "fps", "rocks_ms", "draw_ms", "rocks", "hits"} (medians over the frames; rocks_ms is the rock system's
calls plus the mirror's update; examples/rockgame/budget.py says what each part holds).
"""

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "examples"))

from taichi_rocks.cliparse import whole  # noqa: E402  (the clone's package, whatever the folder)


def _resolution(text: str) -> tuple:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT like 960x540, got {text!r}") from None
    if not (64 <= w <= 7680 and 64 <= h <= 4320):
        raise argparse.ArgumentTypeError(f"each side must be in [64, 7680] x [64, 4320], got {text!r}")
    return w, h


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit status 2 (argparse prints its usage first)
        self.exit(2, f"{self.prog}: {message}\n")


def parse(argv=None) -> argparse.Namespace:
    ap = _Parser(prog="panda3d_game.py", description=__doc__.splitlines()[0])
    ap.add_argument("--offscreen", action="store_true", help="no window: Panda3D's software renderer, scripted "
                                                             "driving on a 60 Hz clock")
    ap.add_argument("--frames", type=whole(1), help="frames to run (offscreen default: 300; a window: until Esc)")
    ap.add_argument("--out", type=Path, metavar="DIR", help="offscreen: write each frame to DIR/frame_NNNN.png "
                                                             "and what the camera saw to DIR/frames.npz")
    ap.add_argument("--resolution", type=_resolution, default=(960, 540), metavar="WxH", help="default 960x540")
    ap.add_argument("--camera", choices=("chase", "cockpit"), default="chase", help="chase (behind the car) or "
                                                                                     "cockpit (the driver's seat)")
    ap.add_argument("--drive", type=Path, metavar="FILE", help="replay a recorded drive (docs/drives.md) instead "
                                                               "of the keyboard (offscreen default: "
                                                               "examples/rockgame/follow.drive)")
    ap.add_argument("--record-drive", type=Path, metavar="FILE", help="write what was driven to FILE at the end")
    ap.add_argument("--rocks", type=whole(0), help="rocks in the bed (default: the scene's 50,000, same density)")
    ap.add_argument("--truck-tires-off", action="store_true", help="the truck throws nothing (a comparison)")
    ap.add_argument("--bare", action="store_true", help="also time a bare Panda3D frame (the rocks as points "
                                                        "re-uploaded whole, nothing else) after each game frame")
    ap.add_argument("--gl", action="store_true", help="a window drawn with OpenGL, not the software renderer")
    ap.add_argument("--overwrite", action="store_true", help="replace frames or a drive file already there")
    return ap.parse_args(argv)


def _problem(args) -> str | None:
    """What is wrong with the arguments beyond their syntax (one line), before anything starts."""
    if args.out is not None and not args.offscreen:
        return "--out: frames are written offscreen only (add --offscreen)"
    if args.out is not None and args.out.exists() and not args.out.is_dir():
        return f"--out: {args.out} is a file, not a folder"
    if args.out is not None and args.out.is_dir() and not args.overwrite and any(args.out.glob("frame_*.png")):
        return f"--out: {args.out} already holds frames (--overwrite replaces them)"
    if args.record_drive is not None and args.record_drive.exists() and not args.overwrite:
        return f"--record-drive: {args.record_drive} exists (--overwrite replaces it)"
    if args.drive is not None and args.record_drive is not None:
        return "--record-drive: a replayed drive is already recorded (it is --drive's file)"
    return None


def has_display() -> bool:
    return sys.platform in ("win32", "darwin") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def main(argv=None) -> int:
    args = parse(argv)
    problem = _problem(args)
    if problem:
        print(f"panda3d_game.py: {problem}", file=sys.stderr)
        return 2
    try:
        import panda3d  # noqa: F401
    except ImportError:
        print("panda3d_game.py: Panda3D is not installed: pip install '.[game]' (or make game)", file=sys.stderr)
        return 2
    from taichi_rocks.config.drivefile import DriveFileError, read_drive
    from rockgame.game import Game, Options
    from rockgame.scene import FOLLOW_DRIVE

    offscreen = args.offscreen
    if not offscreen and not has_display():
        print("no display: running offscreen (--offscreen), scripted driving", file=sys.stderr)
        offscreen = True
    drive = args.drive if args.drive is not None else (FOLLOW_DRIVE if offscreen else None)
    if drive is not None:
        try:
            read_drive(drive)
        except DriveFileError as e:
            print(f"panda3d_game.py: --drive: {e}", file=sys.stderr)
            return 2
    frames = args.frames if args.frames is not None else (300 if offscreen else 0)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    opts = Options(offscreen=offscreen, frames=frames, out=args.out, size=args.resolution, camera=args.camera,
                   drive=drive, rocks=args.rocks, truck_tires=not args.truck_tires_off, bare=args.bare,
                   record_drive=args.record_drive, software=not args.gl)
    game = Game(opts)
    (game.run_offscreen if offscreen else game.run_window)()
    if args.out is not None:
        game.write_log(args.out / "frames.npz")
    if args.record_drive is not None:
        _write_atomic(args.record_drive, game.drive_text())
        print(f"wrote {args.record_drive}: {len(game.sim.drive_track('player'))} poses")
    w, h = opts.size
    print(f"{game.frame_no} frames at {w}x{h}, {game.rocks.n:,} rocks, {game.hits_total()} hits "
          f"({'offscreen, software renderer' if offscreen else 'window'}, camera {game.camera})")
    print(game.budget.table())
    print(game.budget.summary(game.frame_no, game.rocks.n, game.hits_total()))
    game.close()
    return 0


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text)
    os.replace(tmp, path)


if __name__ == "__main__":
    sys.exit(main())
