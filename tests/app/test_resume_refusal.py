"""``render --resume`` refuses frames that another render drew: a changed scene (an edited file, another --seed),
another resolution or rock drawing mode (another frame rate: tests/render/test_render.py). Each refusal is one
line, before anything is drawn, and leaves the interrupted render's frames and saved states byte for byte as
they were (what a resume of the same render reads: tests/render/test_render.py resumes one)."""

import os
from pathlib import Path

import pytest

from cli_util import ROOT

MINIMAL = ROOT / "scenes" / "minimal.toml"
W, H = 160, 96


def _files(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def interrupted(taichi_cpu, tmp_path_factory):
    """A render of the minimal scene (4 frames at 160x96, a state saved after every frame) interrupted while
    drawing frame 2: frames 0 and 1 and their states are kept."""
    from taichi_rocks.app.render import render_scene

    out = tmp_path_factory.mktemp("interrupted") / "out"

    def stop(k, img):
        if k == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_scene(MINIMAL, out_dir=out, frames=4, resolution=(W, H), progress=False, on_frame=stop,
                     checkpoint_every=1)
    assert sorted(os.listdir(out)) == [".resume", "frames"]
    assert sorted(os.listdir(out / "frames")) == ["frame_00000.png", "frame_00001.png"]
    return out, _files(out)


def _refused_by_cli(capsys, out, *args) -> str:
    from taichi_rocks.cli import main

    status = main(["render", str(MINIMAL), "--out", str(out), "--frames", "4", "--resume", *map(str, args)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, (status, err)
    return err[0]


def test_another_seed_is_another_scene(interrupted, capsys):
    out, before = interrupted
    line = _refused_by_cli(capsys, out, "--resolution", f"{W}x{H}", "--seed", 2)
    assert line == (f"taichi-rocks render: cannot resume: the frames in {out} were rendered from another scene, "
                    "frame rate, resolution or rock mode; render again with --overwrite")
    assert _files(out) == before


def test_an_edited_scene_file_is_refused(interrupted, tmp_path):
    from taichi_rocks.app.render import render_scene

    out, before = interrupted
    edited = tmp_path / "minimal.toml"  # the same name: the same output folder
    text = MINIMAL.read_text().replace("[sim]", "[world]\nwetness = 0.5\n\n[sim]")
    assert "wetness = 0.5" in text
    edited.write_text(text)
    with pytest.raises(ValueError) as info:
        render_scene(edited, out_dir=out, frames=4, resolution=(W, H), progress=False, resume=True)
    assert str(info.value).startswith(f"cannot resume: the frames in {out} were rendered from another scene")
    assert _files(out) == before


def test_another_resolution_is_refused_by_the_frames_size(interrupted, capsys):
    out, before = interrupted
    line = _refused_by_cli(capsys, out, "--resolution", f"{W + 32}x{H}")
    assert line == (f"taichi-rocks render: cannot resume: {out / 'frames'} holds {W}x{H} frames, this render is "
                    f"{W + 32}x{H}")
    line = _refused_by_cli(capsys, out)  # no --resolution: the scene's 640x360
    assert line.endswith(f"holds {W}x{H} frames, this render is 640x360")
    assert _files(out) == before


def test_another_rock_mode_is_refused(interrupted):
    from taichi_rocks.app.render import render_scene

    out, before = interrupted
    with pytest.raises(ValueError) as info:
        render_scene(MINIMAL, out_dir=out, frames=4, resolution=(W, H), progress=False, resume=True,
                     rocks="particles")
    assert str(info.value) == (f"cannot resume: the frames in {out} were rendered from another scene, frame rate, "
                               "resolution or rock mode; render again with --overwrite")
    assert _files(out) == before
