"""output/video.py: the frame writer's thread yields the cores to the render loop, and only that thread does."""

import os
import threading

import numpy as np

from taichi_rocks.output import video


def test_the_writer_thread_alone_runs_at_a_lower_priority(tmp_path, monkeypatch):
    seen = {}
    real_encode = video.FrameWriter._encode

    def encode(self, index, img):
        seen["writer"] = os.getpriority(os.PRIO_PROCESS, 0)  # this thread's niceness (Linux: per thread)
        return real_encode(self, index, img)

    monkeypatch.setattr(video.FrameWriter, "_encode", encode)
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    with video.FrameWriter(tmp_path, "t", 30.0, fmt="png") as w:
        w.write(np.zeros((4, 6, 3), np.uint8))
    assert seen["writer"] == min(mine + video.ENCODER_NICENESS, 19)
    assert os.getpriority(os.PRIO_PROCESS, 0) == mine  # the caller's thread is untouched
    assert (tmp_path / "frames" / "frame_00000.png").is_file()
    other = {}
    t = threading.Thread(target=lambda: other.setdefault("p", os.getpriority(os.PRIO_PROCESS, 0)))
    t.start()
    t.join()
    assert other["p"] == mine  # threads started later are not affected either
