"""The README's pictures of the default scene, made from the frames `make demo` writes.

    make demo                       # renders/convoy/frames/frame_00000.png ... frame_00299.png
    python tools/readme_media.py    # renders/media/convoy.gif, convoy_frame.png, convoy_driver.png

* ``convoy_frame.png``: frame 60 (the first shot: beside the truck's rear tire, the spray, the player behind);
* ``convoy_driver.png``: the last frame (the driver's seat, the windscreen marked by the hits so far);
* ``convoy.gif``: every 3rd frame of the driver's shot (from 4 s, frame 120 at 30 frames/s) at 400 x 225, the
  hits flashing and the marks piling up, played at the scene's frame rate.

Stills are 960 x 540. Existing files are replaced (they are the README's, made from the current frames); each
is written under a temporary name and renamed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taichi_rocks.config.scene import load_scene  # noqa: E402
from taichi_rocks.output.atomic import atomic_path  # noqa: E402
STILL = (960, 540)
GIF = (400, 225)


def _frames(folder: Path) -> list:
    frames = sorted(folder.glob("frame_*.png"))
    if not frames:
        raise SystemExit(f"readme_media: no frames in {folder}: run `make demo` first")
    return frames


def _small(path: Path, size) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB").resize(size, Image.LANCZOS))


def _write(path: Path, write) -> None:
    with atomic_path(path, suffix=path.suffix) as tmp:  # the suffix picks imageio's format
        write(tmp)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=Path, default=ROOT / "renders/convoy/frames")
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes/convoy.toml", help="the frames' scene (its fps)")
    ap.add_argument("--out", type=Path, default=ROOT / "renders/media")
    ap.add_argument("--driver-from", type=int, default=120, help="first frame of the driver's shot")
    ap.add_argument("--every", type=int, default=3)
    a = ap.parse_args(argv)
    frames = _frames(a.frames)
    if len(frames) <= a.driver_from:
        raise SystemExit(f"readme_media: {len(frames)} frames in {a.frames}, the driver's shot starts at "
                         f"{a.driver_from}")
    a.out.mkdir(parents=True, exist_ok=True)
    _write(a.out / "convoy_frame.png", lambda p: iio.imwrite(p, _small(frames[60], STILL)))
    _write(a.out / "convoy_driver.png", lambda p: iio.imwrite(p, _small(frames[-1], STILL)))
    gif = [_small(f, GIF) for f in frames[a.driver_from::a.every]]
    ms = round(1000 * a.every / load_scene(a.scene).render.fps)
    _write(a.out / "convoy.gif", lambda p: iio.imwrite(p, np.stack(gif), duration=ms, loop=0))
    print(f"readme_media: {a.out}/convoy_frame.png, convoy_driver.png, convoy.gif ({len(gif)} frames)",
          file=sys.stderr)


if __name__ == "__main__":
    main()
