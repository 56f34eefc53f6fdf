"""Writing rendered frames: PNG files (always) and an MP4 or GIF (optional), each file complete or absent.

* PNG frames ``out_dir/frames/frame_00000.png``: each written under a temporary name in the same folder and
  renamed (``os.replace``) when complete, so a frame on disk is never half written.
* MP4 ``out_dir/<name>.mp4``: H.264 in yuv420p, x264 preset superfast at a constant rate factor ``crf``
  ([render] quality, default :data:`DEFAULT_CRF`) through imageio-ffmpeg. A rock bed is noise to the encoder:
  on 720p frames of the default scene CRF 23 gave ~12 Mbit/s (PSNR 33.3 dB), 26 ~8.3 (31.6 dB), 28 ~6.3
  (30.5 dB); veryfast is ~18 % smaller at the same CRF for twice the encoding time, medium ~20 % for five
  times (more than the render loop can hide in its encoding thread on two cores). Streamed while rendering into
  ``out_dir/.<name>.partial.mp4`` and renamed when closed successfully. ``macro_block_size=2`` keeps the
  frame size exact (the default 16 would silently resize 1280x720 -> 1280x720 but 1920x1080 -> 1920x1088);
  odd sides cannot be encoded in yuv420p and are refused up front.
* GIF ``out_dir/<name>.gif``: assembled from the PNG frames at the end (GIF needs every frame at once), also
  through a temporary name.
* ``close(ok=False)`` (failure or interrupt) removes the partial video and keeps the finished frames.
"""

import os
import queue
import struct
import sys
import threading
import time
import zlib
from pathlib import Path

import imageio
import imageio.v3 as iio
import numpy as np

from ..config.scene import Render

__all__ = ["FrameWriter", "FORMATS", "DEFAULT_CRF", "DEFAULT_PRESET", "frame_name", "output_paths", "finished_frames",
           "existing_size", "png_bytes"]

FORMATS = ("mp4", "gif", "png")
PNG_COMPRESS_LEVEL = 1  # zlib level 1: ~2x faster than 6 for files a few % larger (rock beds are noisy)
DEFAULT_CRF = Render.model_fields["quality"].default  # H.264 constant rate factor: the scene format's default
DEFAULT_PRESET = "superfast"
ENCODER_NICENESS = 10  # the writer thread's (and its ffmpeg's) niceness above the render loop's


def frame_name(index: int) -> str:
    return f"frame_{index:05d}.png"


def output_paths(out_dir, name: str, fmt: str) -> dict:
    """Where a render writes: {"frames": folder, "video": file or None}."""
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    out_dir = Path(out_dir)
    return {"frames": out_dir / "frames", "video": None if fmt == "png" else out_dir / f"{name}.{fmt}"}


def finished_frames(frames_dir) -> int:
    """How many frames frame_00000.png, frame_00001.png, ... exist without a gap (each was written atomically,
    so each is complete)."""
    n = 0
    frames_dir = Path(frames_dir)
    while (frames_dir / frame_name(n)).is_file():
        n += 1
    return n


def existing_size(frames_dir):
    """(W, H) of frame_00000.png, or None."""
    path = Path(frames_dir) / frame_name(0)
    if not path.is_file():
        return None
    h, w = iio.improps(path).shape[:2]
    return (w, h)


def png_bytes(img: np.ndarray, level: int = PNG_COMPRESS_LEVEL) -> bytes:
    """Encode an (H, W, 3|4) uint8 image as PNG: the "sub" filter on every row (NumPy) and one zlib call.

    Pillow compresses in 64 KB blocks and takes the GIL back for each; in a writer thread next to a render
    loop whose Taichi kernels hold the GIL for milliseconds at a time, that starved the writer (20 frames took
    71 s instead of 19 s in a test). NumPy and zlib release the GIL for the whole frame. Same size as
    Pillow's level-1 files (~850 kB for a 720p frame of a rock bed), ~4x faster.
    """
    img = np.ascontiguousarray(img, dtype=np.uint8)
    h, w, c = img.shape
    rows = img.reshape(h, w * c)
    filtered = np.empty((h, 1 + w * c), np.uint8)
    filtered[:, 0] = 1  # filter type "sub": each byte minus the same channel of the pixel on its left
    filtered[:, 1:c + 1] = rows[:, :c]
    np.subtract(rows[:, c:], rows[:, :-c], out=filtered[:, c + 1:])
    data = zlib.compress(filtered, level)

    def chunk(tag: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + tag + payload + struct.pack(">I", zlib.crc32(tag + payload))

    header = struct.pack(">IIBBBBB", w, h, 8, {3: 2, 4: 6}[c], 0, 0, 0)  # 8 bits, RGB or RGBA
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data) + chunk(b"IEND", b"")


def _write_png(path: Path, img: np.ndarray) -> None:
    """Write a PNG atomically: a temporary name in the same folder, renamed when complete."""
    tmp = path.with_name(f".{path.name}.partial")
    try:
        with open(tmp, "wb") as f:
            f.write(png_bytes(img))
        os.replace(tmp, path)
    except BaseException:
        _unlink(tmp)
        raise


def _lower_priority(niceness: int = ENCODER_NICENESS) -> None:
    """Lower the calling thread's scheduling priority (Linux: niceness is per thread, and a process the thread
    starts inherits it). The render loop's kernels run on every core in bursts; an encoder at the same priority
    took half of them for its whole frame. Measured on 2 cores (the default scene, 300 frames at 720p): see the
    frame rates of docs/performance.md. No-op where unsupported."""
    try:
        os.setpriority(os.PRIO_PROCESS, 0, os.getpriority(os.PRIO_PROCESS, 0) + niceness)
    except (AttributeError, OSError):
        pass


def _unlink(path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


class FrameWriter:
    """Write frames as PNG files plus an MP4 or GIF.

    ``fmt``: "mp4", "gif" or "png" (frames only); ``crf``: the MP4's H.264 constant rate factor (0-51, lower is
    better and larger; +6 about halves the size), ``ffmpeg_preset`` x264's speed preset. With ``background=True``
    (default) frames are encoded by one worker thread fed through a short queue, so PNG compression (zlib releases
    the GIL) and the pipe to ffmpeg overlap the next frame's simulation and drawing; :meth:`write` copies the frame
    and blocks only when the queue is full. Errors of the worker are raised by the next :meth:`write` or by
    :meth:`close`. ``timings["encode"]``: seconds the caller spent blocked in write/close;
    ``timings["encode_busy"]``: seconds of actual encoding work (PNG + video), wherever it ran.
    ``start``: resume after frames 0 .. start-1, which are already on disk (they are re-encoded into the
    video first; the next :meth:`write` is frame ``start``).
    Use as a context manager, or call :meth:`close` with ``ok=True`` when every frame was written.
    """

    def __init__(self, out_dir, name: str, fps: float, fmt: str = "mp4", *, start: int = 0, background: bool = True,
                 queue_size: int = 3, ffmpeg_preset: str = DEFAULT_PRESET, crf: int = DEFAULT_CRF):
        paths = output_paths(out_dir, name, fmt)
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        self.out_dir = Path(out_dir)
        self.name = name
        self.fps = float(fps)
        self.fmt = fmt
        self.frames_dir = paths["frames"]
        self.video_path = paths["video"]
        self.start = int(start)  # resuming: frames 0 .. start-1 are on disk already and start the video
        self.frames_written = self.start  # frames on disk or accepted by write()
        self.size = existing_size(paths["frames"]) if self.start else None  # (W, H) of the first frame
        self.closed = False
        self.timings = {"encode": 0.0, "encode_busy": 0.0}
        self.frames_dir.mkdir(parents=True, exist_ok=True)
        for stale in self.frames_dir.glob(".frame_*.png.partial"):  # left by a killed render (kill -9)
            _unlink(stale)
        self._tmp_video = None
        self._writer = None
        self._ffmpeg_params = ["-preset", str(ffmpeg_preset), "-crf", str(int(crf))]
        if fmt in ("mp4", "gif"):
            self._tmp_video = self.out_dir / f".{name}.partial.{fmt}"
            _unlink(self._tmp_video)
        self._error = None
        self._abort = False  # worker: stop encoding (after an error)
        self._drop_video = False  # worker: PNGs only (the render failed; the video will be removed)
        self._queue = self._thread = None
        if background:
            self._queue = queue.Queue(maxsize=max(1, int(queue_size)))
            self._thread = threading.Thread(target=self._work, name="taichi-rocks-frames", daemon=True)
            self._thread.start()

    # --------------------------------------------------------------------------------------------------
    def _open_mp4(self) -> None:
        self._writer = imageio.get_writer(
            str(self._tmp_video), format="FFMPEG", mode="I", fps=self.fps, codec="libx264",
            pixelformat="yuv420p", macro_block_size=2, ffmpeg_log_level="error",
            output_params=self._ffmpeg_params)

    def _encode(self, index: int, img: np.ndarray) -> None:
        t0 = time.perf_counter()
        _write_png(self.frames_dir / frame_name(index), img)
        if self.fmt == "mp4" and not self._drop_video:
            if self._writer is None:
                self._open_mp4()
                self._replay()
            self._writer.append_data(img)
        self.timings["encode_busy"] += time.perf_counter() - t0

    def _replay(self) -> None:
        """Resuming: the frames already on disk start the new video."""
        for i in range(self.start):
            self._writer.append_data(iio.imread(self.frames_dir / frame_name(i)))

    def _work(self) -> None:
        _lower_priority()  # this thread and the ffmpeg it starts yield the cores to the render loop's kernels
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self._abort:
                continue
            try:
                self._encode(*item)
            except BaseException as e:  # reported to the caller by write()/close()
                self._error = e
                self._abort = True

    def _raise_error(self) -> None:
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    def write(self, img: np.ndarray) -> Path:
        """Append one frame, (H, W, 3) uint8; return the path its PNG gets."""
        if self.closed:
            raise RuntimeError("FrameWriter is closed")
        t0 = time.perf_counter()
        try:
            self._raise_error()
            img = np.asarray(img)
            if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
                raise ValueError(f"frames must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
            h, w = img.shape[:2]
            if self.size is None:
                if self.fmt == "mp4" and (w % 2 or h % 2):
                    raise ValueError(f"MP4 (H.264, yuv420p) needs even frame sides, got {w}x{h}")
                self.size = (w, h)
            elif (w, h) != self.size:
                raise ValueError(f"frame {self.frames_written} is {w}x{h}, "
                                 f"the first was {self.size[0]}x{self.size[1]}")
            index = self.frames_written
            if self._thread is not None:
                self._queue.put((index, np.array(img, copy=True)))
            else:
                self._encode(index, img)
            self.frames_written += 1
            return self.frames_dir / frame_name(index)
        finally:
            self.timings["encode"] += time.perf_counter() - t0

    def close(self, ok: bool = True):
        """Finish the video (ok) or drop it (not ok: partial video removed; the PNGs of every frame given to
        :meth:`write` are kept, so a later run can resume). Returns the video path (None for "png", or when not
        ok). Idempotent."""
        if self.closed:
            return self.video_path if ok else None
        self.closed = True
        t0 = time.perf_counter()
        try:
            if self._thread is not None:
                if not ok:
                    self._drop_video = True  # the frames still queued are finished renders: keep their PNGs
                self._queue.put(None)
                self._thread.join()
            if ok and self._error is None and self.fmt == "mp4" and self._writer is None and self.start > 0:
                self._open_mp4()  # resumed with nothing left to draw: the video is the frames on disk
                self._replay()
            if self._writer is not None:
                writer, self._writer = self._writer, None
                writer.close()
            if ok:
                self._raise_error()
            if not ok:
                if self._tmp_video is not None:
                    _unlink(self._tmp_video)
                return None
            if self.fmt == "gif":
                self._assemble_gif()
            if self._tmp_video is not None:
                if self.frames_written == 0:
                    _unlink(self._tmp_video)
                    return None
                os.replace(self._tmp_video, self.video_path)
            return self.video_path
        except BaseException:
            if self._tmp_video is not None:
                _unlink(self._tmp_video)
            raise
        finally:
            self.timings["encode"] += time.perf_counter() - t0

    def _assemble_gif(self) -> None:
        if self.frames_written == 0:
            return
        t0 = time.perf_counter()
        frames = [iio.imread(self.frames_dir / frame_name(i)) for i in range(self.frames_written)]
        iio.imwrite(self._tmp_video, np.stack(frames), extension=".gif", duration=1000.0 / self.fps, loop=0)
        self.timings["encode_busy"] += time.perf_counter() - t0

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(ok=exc_type is None)
        return False


if __name__ == "__main__":  # pragma: no cover - manual check
    w = FrameWriter(sys.argv[1], "check", 30.0, "mp4")
    for k in range(10):
        w.write(np.full((64, 96, 3), k * 20, np.uint8))
    print(w.close())
