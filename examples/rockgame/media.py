"""The README's stills of the game: examples/panda3d_game.py offscreen over the shipped drive (follow.drive), from
the chase camera at 6.7 s (the car 3-4 m behind the truck, stones streaking between them) and from the driver's
seat at 5.1 s (stones in the air, a hit flashing, the glass cracked), at 960x540, downscaled to 800x450 (the chase
view's gravel in 256 colours: under 300 KB) and written to docs/media/game-chase.png and game-cockpit.png.

    python examples/rockgame/media.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
GAME = ROOT / "examples" / "panda3d_game.py"
FRAMES = {"chase": 400, "cockpit": 304}
COLOURS = {"chase": 256, "cockpit": None}  # a palette where the full colours would pass 300 KB
SIZE = (800, 450)


def main() -> int:
    media = ROOT / "docs" / "media"
    for camera, frame in FRAMES.items():
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run([sys.executable, str(GAME), "--offscreen", "--frames", str(frame), "--resolution",
                            "960x540", "--camera", camera, "--out", tmp], check=True, stdout=subprocess.DEVNULL)
            img = Image.open(Path(tmp) / f"frame_{frame:04d}.png").convert("RGB").resize(SIZE, Image.LANCZOS)
            if COLOURS[camera]:
                img = img.quantize(COLOURS[camera], method=Image.Quantize.MEDIANCUT)
            out = media / f"game-{camera}.png"
            part = out.with_name(out.stem + ".part.png")
            img.save(part, optimize=True)
            os.replace(part, out)
            print(f"wrote {out}: {out.stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
