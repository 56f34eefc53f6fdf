"""Memory of a long `taichi-rocks view` session: the resident set size (RSS) of the window's process, sampled
every few seconds while it plays, and the frames per second it reports.

    python tools/view_memory.py scenes/convoy.toml --seconds 600 --every 30 --resolution 1280x720

Runs the viewer under the current DISPLAY, or under a private Xvfb if there is none (`Xvfb` must be
installed: tools/setup.sh). Prints one line per sample (seconds since the first frame, RSS in MB, frame shown,
fps) and a JSON summary on the last line.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _xvfb():
    for n in range(60, 100):
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists():
            proc = subprocess.Popen(["Xvfb", f":{n}", "-screen", "0", "1920x1080x24", "-nolisten", "tcp"],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            for _ in range(100):
                if subprocess.run(["xdpyinfo", "-display", f":{n}"], capture_output=True).returncode == 0:
                    return proc, f":{n}"
                time.sleep(0.1)
            proc.kill()
    raise SystemExit("view_memory: could not start Xvfb")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene", type=Path)
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--every", type=float, default=30.0)
    ap.add_argument("--resolution", default=None)
    args = ap.parse_args()
    xvfb, display = (None, os.environ["DISPLAY"]) if os.environ.get("DISPLAY") else _xvfb()
    with tempfile.TemporaryDirectory() as tmp:
        status = Path(tmp) / "status.json"
        env = dict(os.environ, DISPLAY=display, PYTHONPATH=str(ROOT), TAICHI_ROCKS_VIEW_STATUS=str(status))
        cmd = [sys.executable, "-m", "taichi_rocks", "view", str(args.scene), "--quit-after", str(args.seconds)]
        if args.resolution:
            cmd += ["--resolution", args.resolution]
        proc = subprocess.Popen(cmd, env=env, cwd=tmp)
        samples = []
        try:
            while not status.exists() and proc.poll() is None:
                time.sleep(0.2)
            t0 = time.perf_counter()
            while proc.poll() is None:
                t = time.perf_counter() - t0
                try:
                    st = json.loads(status.read_text())
                    rss = _rss_mb(proc.pid)
                except (OSError, ValueError):
                    break
                samples.append({"s": round(t), "rss_mb": round(rss, 1), "frame": st["frame"],
                                "shown": st["shown"], "fps": round(st["fps"], 1),
                                "window_refreshes": st.get("window_refreshes", 0)})
                print(f"{t:6.0f} s  RSS {rss:7.1f} MB  frames shown {st['shown']:6d}  fps {st['fps']:5.1f}  "
                      f"window refreshes {st.get('window_refreshes', 0)}", flush=True)
                while proc.poll() is None and time.perf_counter() - t0 < t + args.every:
                    time.sleep(0.5)
        finally:
            code = proc.wait()
            if xvfb is not None:
                xvfb.terminate()
    rss = [s["rss_mb"] for s in samples]
    print(json.dumps({"scene": str(args.scene), "exit": code, "samples": samples,
                      "rss_first_mb": rss[0] if rss else None, "rss_last_mb": rss[-1] if rss else None,
                      "rss_max_mb": max(rss) if rss else None}))


if __name__ == "__main__":
    main()
