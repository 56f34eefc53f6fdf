"""README.md's measured tables are what tools/readme_tables.py makes of the committed results (docs/results/
bench.json from ``taichi-rocks bench``, launch.json from ``taichi-rocks bench --only launch``, impacts.json from
``taichi-rocks bench --only impacts``): every number in
them traces to an artefact. After a new run: copy its results there and run ``python tools/readme_tables.py``."""

import copy
import importlib.util

from cli_util import ROOT

_spec = importlib.util.spec_from_file_location("readme_tables", ROOT / "tools" / "readme_tables.py")
tables = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tables)


def test_readme_blocks_equal_what_the_script_makes_of_the_committed_results():
    text = tables.README.read_text()
    generated = tables.blocks(*tables.load())
    assert tables.rewrite(text, generated) == text, "run: python tools/readme_tables.py"
    for name, body in generated.items():
        assert body.strip() and f"<!-- results:{name} -->\n{body}\n<!-- /results:{name} -->" in text, name


def test_every_target_of_the_results_is_in_the_readme():
    launch, bench = tables.load()
    text = tables.README.read_text()
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


def test_a_changed_result_changes_the_readme():
    launch, bench = tables.load()
    text = tables.README.read_text()
    changed = copy.deepcopy(bench)
    t = next(t for t in changed["targets"] if t["target"].startswith(tables.SPEED_TARGETS))
    t["met"] = not t["met"]
    assert tables.rewrite(text, tables.blocks(launch, changed)) != text
    changed = copy.deepcopy(launch)
    changed["stats"]["V20 dry gravel"]["launches"] += 1
    assert tables.rewrite(text, tables.blocks(changed, bench)) != text
    changed = copy.deepcopy(bench)
    changed["impacts_run"]["impacts"]["targets"][0]["met"] = not changed["impacts_run"]["impacts"]["targets"][0]["met"]
    assert tables.rewrite(text, tables.blocks(launch, changed)) != text
