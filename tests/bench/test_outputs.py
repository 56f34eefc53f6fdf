"""The benchmark's files are written like every other output: whole or not at all, by a rename over the old
file (output/recording.py write_atomically), never rewritten in place. Checked on canned results, with a
hard link to the old file: a file rewritten in place would show the new content through the link too."""

import json
import os

from taichi_rocks.bench import plots, report


def _earlier(path):
    """An earlier run's file at ``path`` and a second name for its bytes (a hard link); returns the link."""
    path.write_text("earlier run")
    link = path.with_name("link_to_" + path.name)
    os.link(path, link)
    return link


def _only_finals(folder, *names):
    assert sorted(p.name for p in folder.iterdir()) == sorted(names)  # no temporaries left beside them


def test_report_and_results_replace_the_old_files_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(report, "_SECTIONS", (lambda res, plots: ["# canned", f"{res['n']} rocks"],))
    links = [_earlier(tmp_path / "report.md"), _earlier(tmp_path / "results.json")]
    res = {"n": 7, "_private": object()}
    assert report.write_report(res, tmp_path, []) == tmp_path / "report.md"
    assert report.write_results(res, tmp_path) == tmp_path / "results.json"
    assert (tmp_path / "report.md").read_text() == "# canned\n7 rocks"
    assert json.loads((tmp_path / "results.json").read_text()) == {"n": 7}
    assert [link.read_text() for link in links] == ["earlier run"] * 2
    _only_finals(tmp_path, "report.md", "results.json", *(link.name for link in links))


def test_a_plot_replaces_the_old_file_whole(tmp_path):
    plt = plots._plt()
    fig, ax = plt.subplots(figsize=(2, 1))
    ax.plot([0, 1], [1, 0])
    link = _earlier(tmp_path / plots.PNG["peers"])
    assert plots._save(plt, fig, tmp_path, plots.PNG["peers"]) == "speed_peers.png"
    assert (tmp_path / "speed_peers.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert link.read_text() == "earlier run"
    _only_finals(tmp_path, "speed_peers.png", link.name)
