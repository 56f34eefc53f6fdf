"""The measured tables of README.md and docs/ are what tools/readme_tables.py makes of the committed results
(docs/results/ bench.json from ``taichi-rocks bench``, launch.json from ``taichi-rocks bench --only launch``,
impacts.json from ``taichi-rocks bench --only impacts``, frame.json from ``taichi-rocks bench --only frame`` when
it is committed): every number in them traces to an artefact. After a new run: copy its results there and run
``python tools/readme_tables.py``."""

import copy
import importlib.util

from cli_util import ROOT

_spec = importlib.util.spec_from_file_location("readme_tables", ROOT / "tools" / "readme_tables.py")
tables = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tables)


def _all_text() -> str:
    return "\n".join(page.read_text() for page in tables.PAGES)


def test_every_page_holds_what_the_script_makes_of_the_committed_results():
    generated = tables.blocks(*tables.load())
    assert set(generated) == {name for names in tables.PAGES.values() for name in names}, "a block on no page"
    for page, names in tables.PAGES.items():
        text = page.read_text()
        assert tables.rewrite(text, generated, names, page.name) == text, f"{page}: run python tools/readme_tables.py"
        for name in names:
            body = generated[name]
            if name in ("frame", "frame-details") and not (tables.RESULTS / "frame.json").exists():
                # the frame run is not committed yet: its blocks are there and empty
                assert f"<!-- results:{name} -->\n<!-- /results:{name} -->" in text, page
                continue
            assert body.strip() and f"<!-- results:{name} -->\n{body}\n<!-- /results:{name} -->" in text, (page, name)


def test_every_target_of_the_results_is_on_a_page():
    launch, bench = tables.load()
    text = _all_text()
    for row in launch["table"]:
        assert f"| {row['target']} | {row['shown']} |" in text, row["target"]
    judged = [t for t in bench["targets"] if t["target"].startswith(tables.SPEED_TARGETS + tables.ACTIVITY_TARGETS)]
    assert len(judged) >= 8
    for t in judged:
        assert f"| {t['target']} |" in text, t["target"]
    impacts = bench["impacts_run"]["impacts"]["targets"]
    assert len(impacts) >= 7
    for t in impacts:
        assert f"| {t['target']} | {t['shown']} |" in text, t["target"]


def test_the_readme_shows_the_headline_figures():
    text = tables.README.read_text()
    for name in ("headline-speed", "frame", "presets"):
        assert f"<!-- results:{name} -->" in text, name
    launch, bench = tables.load()
    peers = tables._grid(bench)[tuple(bench["config"]["main"])]["peers"]
    assert f"| {tables._num(peers['warp_ms'])} |" in text and f"| {tables._num(peers['numpy_ms'])} |" in text


def _changes_a_page(launch, bench) -> bool:
    generated = tables.blocks(launch, bench)
    return any(tables.rewrite(p.read_text(), generated, names) != p.read_text() for p, names in tables.PAGES.items())


def test_a_changed_result_changes_a_page():
    launch, bench = tables.load()
    changed = copy.deepcopy(bench)
    t = next(t for t in changed["targets"] if t["target"].startswith(tables.SPEED_TARGETS))
    t["met"] = not t["met"]
    assert _changes_a_page(launch, changed)
    changed = copy.deepcopy(launch)
    changed["stats"]["V20 dry gravel"]["launches"] += 1
    assert _changes_a_page(changed, bench)
    changed = copy.deepcopy(bench)
    changed["impacts_run"]["impacts"]["targets"][0]["met"] = not changed["impacts_run"]["impacts"]["targets"][0]["met"]
    assert _changes_a_page(launch, changed)
    changed = copy.deepcopy(bench)
    n, t = changed["config"]["main"]
    tables._grid(changed)[(n, t)]["peers"]["warp_ms"] *= 2
    assert _changes_a_page(launch, changed)


def test_a_frame_run_fills_the_frame_blocks_and_its_absence_empties_them():
    launch, bench = tables.load()
    stats = {"median_ms": 0.25, "p95_ms": 0.5, "max_ms": 1.0}
    loop = {"case": "game", "threads_asked": "auto", "threads": 2, "steps_per_frame": 1.0, "rows_median": 2786.0,
            "loops_asked": "auto", "loops": "serial",
            **{k: stats for k in ("advance_to", "impacts", "changes", "state")},
            "frame": {"median_ms": 0.8, "p95_ms": 1.25, "max_ms": 2.0}}
    frame_run = {"started": "2026-12-04 20:00:00", "load_average_start": [0.1, 0.1, 0.1],
                 "machine": {"cpu_model": "X", "usable_cores": 2, "taichi": "1.7.4", "taichi_arch": "cpu"},
                 "loops": [loop], "tasks": {"serial": {"tasks": [{"kernel": "active_step", "task": 0, "what": "rays in",
                                                                  "kind": "serial", "per_step": 1.0, "median_ms": 0.002,
                                                                  "share": 0.25}],
                                                       "device_ms_per_step": 0.008, "tasks_per_step": 1.0,
                                                       "parallel_tasks_per_step": 0.0, "active": 1500}},
                 "variants": {"rows": [{"rocks": 20_000, "serial_ms": 1.5, "parallel_ms": 2.5},
                                       {"rocks": 200_000, "serial_ms": 9.0, "parallel_ms": 6.0}],
                              "crossover": 98_000, "threads": 2,
                              "task_costs": {"rows": [{"items": 1000, "parallel_us": 70.0, "serial_us": 14.0,
                                                       "four_parallel_us": 150.0}], "empty_us": 12.5, "threads": 2}},
                 "accuracy": [{"preset": "game", "dt": 1 / 60, "steps_per_60hz_frame": 1.0, "integrator": "heun",
                               "detection": "patch", "precision": "f32", "flight_error_m": 1e-3,
                               "recall_at_60": 1.0, "launch_time_bound_m": 0.5}]}
    got = tables.blocks(launch, dict(bench, frame_run=frame_run))
    assert ("| game | 2 (auto) | serial (auto) | 1 | 0.25 ms | 0.25 ms | 0.25 ms (2,786) | **0.8 ms** | 1.25 ms | "
            "0.25 ms |") in got["frame"]
    assert "| serial | active_step | 0 | rays in | serial | 1 | 2 | 25 % |" in got["frame-details"]
    assert "| 200,000 | 9 ms | 6 ms | parallel |" in got["frame-details"]  # the variants' crossover
    assert "Crossover: about 98,000 rocks (2 threads)." in got["frame-details"]
    assert "| 1,000 items | 70 µs | 14 µs | 150 µs |" in got["frame-details"]  # what a task costs
    assert "| game | 0.01667 | 1 | heun, patch, f32 | 0.001 | 1 | 0.5 |" in got["frame-details"]
    without = {k: v for k, v in bench.items() if k != "frame_run"}
    assert tables.blocks(launch, without)["frame"] == "" == tables.blocks(launch, without)["frame-details"]
    text = "a\n<!-- results:frame -->\nold\n<!-- /results:frame -->\nb\n"
    assert tables.rewrite(text, {"frame": ""}) == "a\n<!-- results:frame -->\n<!-- /results:frame -->\nb\n"


def test_a_render_profile_fills_the_frame_table_of_the_rendering_page():
    """docs/rendering.md's table of the renderer's frame is what the script makes of a ``render --profile`` run
    (its profile.json): a row per stage in ms per frame, its share of the frame and its CPU ms; without the run
    the block is empty."""
    launch, bench = tables.load()
    stages = ("simulation", "camera", "culling", "marks", "declare", "readback", "sky_ground", "dust", "window")
    run = {"started": "2026-12-05 02:00:00", "scene": "convoy", "frames": 100, "resolution": [1280, 720],
           "frames_per_second": 10.0, "load_average_start": [0.1, 0.1, 0.1], "load_average_end": [1.9, 1.0, 0.5],
           "machine": {"cpu_model": "X", "usable_cores": 2, "taichi": "1.7.4", "taichi_arch": "cpu"},
           "profile": {**{k: 1.0 for k in stages}, "culling": 3.0, "encoding": 0.5, "other": 0.25},
           "profile_cpu": {**{k: 2.0 for k in stages}, "loop": 25.0}}
    got = tables.blocks(launch, dict(bench, render_run=run))["render-frame"]
    assert "| culling | the rock pass: culling, splatting the resting rocks, compacting the flying ones | 30.0 | 30% | " \
           "20.0 |" in got
    assert "| simulation | the simulation stepped to the frame's time (the engine) | 10.0 | 10% | 20.0 |" in got
    assert "| **the frame** | 100 frames at 10.00 frames/s | **100.0** | 100% | 250.0 " in got
    assert "`convoy` at 1280x720" in got and "busy" not in got
    assert "busy" in tables.blocks(launch, dict(bench, render_run=dict(run, load_average_start=[1.8, 1, 1])))[
        "render-frame"]
    without = {k: v for k, v in bench.items() if k != "render_run"}
    assert tables.blocks(launch, without)["render-frame"] == ""
    assert "<!-- results:render-frame -->" in (tables.DOCS / "rendering.md").read_text()
