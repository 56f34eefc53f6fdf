"""The reference pages generated from the code (tools/gen_docs.py) are current: docs/scene-format.md from the scene
models, docs/cli.md and the README's command table from the argument parser, the viewer's keys and sliders in
docs/rendering.md from app/view.py KEYS and engine/params.py SLIDERS. After a change to any of them: run
``python tools/gen_docs.py``."""

import ast
import importlib.util
import inspect
import textwrap

import taichi as ti
from pydantic import BaseModel

from cli_util import ROOT
from taichi_rocks.app import view
from taichi_rocks.config import models
from taichi_rocks.engine.params import SLIDERS

_spec = importlib.util.spec_from_file_location("gen_docs", ROOT / "tools" / "gen_docs.py")
gen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen)


def test_the_generated_pages_are_what_the_code_makes():
    assert gen.stale() == [], "run: python tools/gen_docs.py"


def _section(text: str, heading: str) -> str:
    start = text.index(f"## `{heading}`\n" if heading != "Top level" else "## Top level\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def _tables(model, seen):
    """Every table model under ``model``, found from the annotations (not from the generator's list)."""
    seen.add(model)
    for f in model.model_fields.values():
        stack = [f.annotation]
        while stack:
            a = stack.pop()
            if isinstance(a, type) and issubclass(a, BaseModel):
                if a not in seen:
                    _tables(a, seen)
                continue
            stack.extend(getattr(a, "__args__", ()))
            if hasattr(a, "__metadata__"):  # Annotated[X, ...]: look at X
                stack.append(a.__origin__)
    return seen


def test_every_key_of_every_table_has_a_row_in_its_section():
    text = gen.SCENE_FORMAT.read_text()
    sections = {m: h for h, m, _, _ in gen.SECTIONS}
    tables = _tables(models.Scene, set())
    assert len(tables) == len(sections) == 18 and tables == set(sections)
    rows = 0
    for model, heading in sections.items():
        part = _section(text, heading)
        for name, f in model.model_fields.items():
            if model is models.Scene and gen._is_table(f):
                continue
            key = f.alias or name
            assert f"| `{key}` |" in part, f"{heading} {key}"
            assert " ".join((f.description or "").split()).replace("|", "\\|") in part, f"{heading} {key}"
            rows += 1
        assert "```toml" in part, heading
    assert rows >= 114
    for key in ("| `tumble` |", "| `spin_spread` |"):  # once missing from the hand-written page
        assert key in text


def test_a_changed_description_or_default_makes_the_page_stale(monkeypatch):
    field = models.Launch.model_fields["grip"]
    monkeypatch.setattr(field, "description", "a new description of the clamp")
    assert "a new description of the clamp" in gen.scene_format()
    assert gen.SCENE_FORMAT in gen.stale()


def test_a_bad_example_stops_the_generation(monkeypatch):
    bad = tuple((h, m, w, "[world]\ngravity = -1.0\n" if h == "[world]" else e) for h, m, w, e in gen.SECTIONS)
    monkeypatch.setattr(gen, "SECTIONS", bad)
    try:
        gen.scene_format()
    except SystemExit as e:
        assert "[world]" in str(e) and "gravity" in str(e)
    else:
        raise AssertionError("an invalid example was accepted")


def test_the_cli_page_has_every_command_and_option():
    text = gen.CLI.read_text()
    readme = gen.README.read_text()
    commands = gen._commands()
    assert [name for name, _, _ in commands] == ["check", "schema", "simulate", "export", "render", "view", "aot", "bench",
                                                 "sweep"]
    parts = {chunk.split("\n", 1)[0]: chunk for chunk in text.split("\n## ")[1:]}
    for name, parser, what in commands:
        part = parts[name]
        assert what[1:] in part and f"| `taichi-rocks {name}" in readme, name
        for action in parser._actions:
            for flag in action.option_strings:
                if flag not in ("-h", "--help"):
                    assert f"`{flag}" in part, (name, flag)


def _answered_keys() -> set:
    """The keys Viewer._keys compares the pressed key with: ti.ui.NAME attributes and string literals."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(view.Viewer._keys)))
    keys = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Name) and node.left.id == "k":
            for c in node.comparators:
                for leaf in ([c] if not isinstance(c, ast.Tuple) else c.elts):
                    if isinstance(leaf, ast.Constant):
                        keys.add(leaf.value)
                    else:
                        assert isinstance(leaf, ast.Attribute), ast.dump(leaf)
                        keys.add(getattr(ti.ui, leaf.attr))
    return keys


def test_the_key_table_is_what_the_viewer_answers():
    table = {k for ggui, _, _ in view.KEYS for k in ggui}
    assert _answered_keys() == table and len(table) == 10
    text = gen.RENDERING.read_text()
    for _, label, _ in view.KEYS:
        assert f"| {label} |" in text, label


def test_the_slider_table_is_the_panels():
    text = gen.RENDERING.read_text()
    assert len(SLIDERS) >= 8
    for key, (label, lo, hi) in SLIDERS.items():
        assert f"| {label} | `{key}` | {gen._number(float(lo))} | {gen._number(float(hi))} |" in text, key
