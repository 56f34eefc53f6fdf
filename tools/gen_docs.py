"""The reference pages that are generated from the code, so that they cannot drift from it:

    docs/scene-format.md   every key of a scene file, from the pydantic models (config/models.py, config/impacts.py):
                           type, default, range and description, grouped by table, with one example per table
    docs/cli.md            every command and option, from the argument parser (taichi_rocks/cliparse.py ``parser``)
    README.md              the block ``commands``: one line per command, from the same parser
    docs/rendering.md      the blocks ``view-keys`` (app/view.py ``KEYS`` and ``DRIVE_KEYS``) and ``view-sliders`` (engine/params.py
                           ``SLIDERS``)
    docs/records.md        every field of the typed records (config/records.py: the state, the changes, the
                           checkpoint, the export frame): its unit and what it is

    python tools/gen_docs.py            # write them
    python tools/gen_docs.py --check    # exit 1 (and say which) if a page differs from what the code makes

A generated block sits between ``<!-- generated:NAME -->`` and ``<!-- /generated:NAME -->``; the text around it is
written by hand. tests/test_gen_docs.py runs the check. The examples below are parsed as scenes each time the
pages are made, so an example that no longer validates stops the generation.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pydantic import BaseModel  # noqa: E402
from pydantic_core import PydanticUndefined  # noqa: E402

from taichi_rocks.config import impacts as _impacts, models  # noqa: E402
from taichi_rocks.config.scene import SceneError, parse_scene  # noqa: E402

SCENE_FORMAT = ROOT / "docs" / "scene-format.md"
CLI = ROOT / "docs" / "cli.md"
README = ROOT / "README.md"
RENDERING = ROOT / "docs" / "rendering.md"
RECORDS = ROOT / "docs" / "records.md"

# (heading, model, where its keys sit, an example of the table: TOML text that is valid in a scene with one vehicle)
VEHICLE = '[[vehicle]]\nname = "player"\n'
SECTIONS = (
    ("Top level", models.Scene, "the file's first lines, before any table",
     'name = "convoy"\nduration = 10.0\nseed = 1\n'),
    ("[world]", models.Environment, "`[world]`", '[world]\ngravity = 9.81\nwetness = 0.5     # damp ground\n'),
    ("[bed]", models.Bed, "`[bed]`",
     '[bed]\nfollow = "player"\nradius = 30.0\nrocks = 200000\nrock_radius = [0.015, 0.05]\n'),
    ("[launch]", models.Launch, "`[launch]` (how the rear tires throw rocks: docs/physics.md, \"The throw\")",
     '[launch]\nmodel = "tread"\ngrip = 2.0e5\nadhesion = 3.0e4\nspread = 8.0\n'),
    ("[effects]", models.Effects, "`[effects]` (switches compiled into the kernels)",
     '[effects]\nimpacts = true\ndrag = "linear"\n'),
    ("[impacts]", _impacts.Impacts, "`[impacts]` (with `[effects] impacts = true`: docs/physics.md, \"Impacts\")",
     '[impacts]\nrestitution = 0.5\ndamage_by = "momentum"\n'),
    ("[dust]", models.EFFECTS["dust"].Table, "`[dust]` (with `[effects] dust = true`: docs/physics.md, \"Dust\")",
     '[dust]\nrate = 2.0\nwind = [1.5, 0.0]\n'),
    ("[sim]", models.Sim, "`[sim]`", '[sim]\naccuracy = "balanced"\ndetection = "patch"   # set keys win over the '
                                     'preset\n'),
    ("[sim.hash]", models.Hash, "`[sim.hash]`", '[sim.hash]\ninsert = "center"\ncell_size = "auto"\n'),
    ("[[vehicle]]", models.Vehicle, "`[[vehicle]]`, one table per vehicle (at least one)",
     '[[vehicle]]\nname = "truck"\nlength = 8.0\nwidth = 2.5\nheight = 3.2\nwheelbase = 5.0\ntrack = 2.1\n'
     'tire_radius = 0.5\ntire_width = 0.3\ncolor = "#3366cc"\npath = { points = [[10.5, 0.0], [270.5, 0.0]], '
     'speed = 20.0 }\n'),
    ("vehicle.path: waypoints", models.WaypointPath, "`path` of a `[[vehicle]]`, `kind = \"waypoints\"` (the "
                                                     "default kind)",
     VEHICLE + 'path = { points = [[0, 0], [100, 0], [150, 40]], speed = [10.0, 20.0, 15.0], smooth = true }\n'),
    ("vehicle.path: circle", models.CirclePath, "`path` of a `[[vehicle]]`, `kind = \"circle\"`",
     VEHICLE + 'path = { kind = "circle", center = [0.0, 0.0], radius = 25.0, speed = 12.0 }\n'),
    ("vehicle.path: live", models.LivePath, "`path` of a `[[vehicle]]`, `kind = \"live\"` (driven by `Simulation.drive` "
                                            "or `view --drive`: docs/drives.md)",
     VEHICLE + 'path = { kind = "live", start = [0.0, 0.0], heading = 0.0, speed = 20.0 }\n'),
    ("vehicle.path: recorded", models.RecordedPath, "`path` of a `[[vehicle]]`, `kind = \"recorded\"` (a drive "
                                                    "recorded by `view --record-drive`: docs/drives.md)",
     VEHICLE + 'path = { kind = "recorded", file = "../examples/swerve.drive" }   # in examples/, seen from scenes/\n'),
    ("[camera]", models.CameraSettings, "`[camera]` (the camera of `render`, `view` and `export`)",
     '[camera]\nview = "chase"\nlook_ahead = 6.0\nfov = 50.0\n'),
    ("[[camera.shot]]", models.Shot, "`[[camera.shot]]`, one table per cut, in increasing `at`",
     '[[camera.shot]]\nat = 0.0\nview = "low"\noffset = [-1.0, 3.6, 0.6]\n\n[[camera.shot]]\nat = 4.0\n'
     'view = "driver"\n'),
    ("[render]", models.Render, "`[render]`", '[render]\nresolution = [1920, 1080]\nfps = 60.0\nquality = 23\n'),
    ("render.sun: angles", models.SunAngles, "`sun` of `[render]` given by its angles",
     '[render]\nsun = { azimuth = 129.3, elevation = 54.6 }\n'),
)

INTRO = """\
# Scene file format (TOML)

One scene per file (the shipped ones are in `scenes/`), UTF-8 text (a leading byte-order mark is ignored; other
encodings are refused with the offending byte's offset). SI units, world Z up, angles in degrees in files (radians
in code). Every key has a default except the `[[vehicle]]` tables (at least one vehicle is required) and the
keys marked "required" below. Unknown keys and values are errors with a close-match suggestion
(`sim.integrator: unknown value "rk5", did you mean "rk4"?`). Arrays and inline tables may be nested at most 32
levels inside one another (a scene needs 5); a deeper value is refused with its line before the file is parsed.
`taichi-rocks schema` prints the JSON Schema made from the same models; with the *Even Better TOML* extension (VS
Code) or taplo, put `#:schema ./scene.schema.json` on a scene's first line for completion and validation.

A minimal scene:

```toml
duration = 5.0
[bed]
rocks = 50000
[[vehicle]]
name = "player"
path = { points = [[0.0, 0.0], [100.0, 0.0], [150.0, 40.0]], speed = 15.0 }
```

*This page is generated from the scene models by `python tools/gen_docs.py` (tests/test_gen_docs.py checks that
it is current): edit the models' descriptions, not this page.*
"""


# ------------------------------------------------------------------------------------------------ scene format
def _toml(v) -> str:
    """A default as it would be written in a scene file."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def _number(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _bounds(s: dict) -> str:
    lo = (("[", s["minimum"]) if "minimum" in s else ("(", s["exclusiveMinimum"]) if "exclusiveMinimum" in s
          else None)
    hi = (("]", s["maximum"]) if "maximum" in s else (")", s["exclusiveMaximum"]) if "exclusiveMaximum" in s
          else None)
    if lo and hi:
        out = f"{lo[0]}{_number(lo[1])}, {_number(hi[1])}{hi[0]}"
    elif lo:
        out = (">= " if lo[0] == "[" else "> ") + _number(lo[1])
    elif hi:
        out = ("<= " if hi[0] == "]" else "< ") + _number(hi[1])
    else:
        out = ""
    if "multipleOf" in s:
        out += (", " if out else "") + f"multiple of {_number(s['multipleOf'])}"
    if "minLength" in s and s.get("type") == "string":
        out += (", " if out else "") + "not empty"
    if "pattern" in s:
        out += (", " if out else "") + "#rrggbb"
    return out


def _kind(s: dict, defs: dict) -> tuple[str, str]:
    """(type, range) of a JSON Schema node, in words."""
    if "$ref" in s:
        name = s["$ref"].split("/")[-1]
        return f"table ({defs.get(name, {}).get('title', name)})", ""
    if "enum" in s:
        return " | ".join(f"`{_toml(v)}`" for v in s["enum"]), ""
    if "const" in s:
        return f"`{_toml(s['const'])}`", ""
    alts = s.get("anyOf") or s.get("oneOf")
    if alts:
        parts = [_kind(a, defs) for a in alts if a.get("type") != "null"]
        return " or ".join(t for t, _ in parts), "; ".join(dict.fromkeys(r for _, r in parts if r))
    t = s.get("type")
    if t == "array":
        if "prefixItems" in s:
            items = [_kind(a, defs) for a in s["prefixItems"]]
            kinds = {k for k, _ in items}
            ranges = {r for _, r in items if r}
            text = f"[{', '.join(k for k, _ in items)}]" if len(kinds) > 1 else f"[{len(items)} x {items[0][0]}]"
            return text, "; ".join(sorted(ranges))
        item, rng = _kind(s.get("items", {}), defs)
        extra = f"at least {s['minItems']} " if s.get("minItems") else ""
        return f"list of {extra}{item}", rng
    return {"number": "float", "integer": "int", "boolean": "bool", "string": "str"}.get(t, t or "any"), _bounds(s)


def _default(field) -> str:
    d = field.default
    if d is PydanticUndefined:
        return "required"
    if d is None:
        return "none"
    if isinstance(d, BaseModel):
        return "table"
    if isinstance(d, tuple) and not d:
        return "none"
    return f"`{_toml(d)}`"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _rows(model: type[BaseModel]) -> list[str]:
    schema = model.model_json_schema(by_alias=True)
    defs = schema.get("$defs", {})
    rows = ["| key | type | default | range | description |", "|---|---|---|---|---|"]
    for name, field in model.model_fields.items():
        key = field.alias or name
        kind, rng = _kind(schema["properties"][key], defs)
        rows.append(f"| `{key}` | {_cell(kind)} | {_cell(_default(field))} | {_cell(rng)} | "
                    f"{_cell(field.description or '')} |")
    return rows


def _check_example(heading: str, text: str) -> None:
    """The example parsed as (part of) a scene: with a vehicle added where it has none."""
    data = tomllib.loads(text)
    data.setdefault("vehicle", [{"name": "player"}])
    try:
        # as a scene file in scenes/ (the folder a recorded drive's file name is read from)
        parse_scene(data, source=str(ROOT / "scenes" / "scene-format-example.toml"))
    except SceneError as e:
        raise SystemExit(f"gen_docs: the example of {heading} is not a valid scene: {e}") from None


def _reachable(model: type[BaseModel], seen: set) -> set:
    """Every table model a scene can hold, from ``model`` down."""
    seen.add(model)
    for field in model.model_fields.values():
        for sub in re.findall(r"\b(\w+)\b", repr(field.annotation)):
            m = getattr(models, sub, None) or getattr(_impacts, sub, None)
            if isinstance(m, type) and issubclass(m, BaseModel) and m not in seen and m.__module__.startswith(
                    "taichi_rocks.config"):
                _reachable(m, seen)
    return seen


def scene_format() -> str:
    documented = {m for _, m, _, _ in SECTIONS}
    missing = _reachable(models.Scene, set()) - documented
    if missing:
        raise SystemExit(f"gen_docs: tables without a section: {sorted(m.__name__ for m in missing)}")
    keys = sum(len(m.model_fields) for m in documented if m is not models.Scene) + sum(
        1 for f in models.Scene.model_fields.values() if not _is_table(f))
    out = [INTRO, f"{keys} keys in {len(SECTIONS) - 1} tables and the top level.", ""]
    out += ["Contents: " + ", ".join(f"[`{h}`](#{_anchor(h)})" for h, _, _, _ in SECTIONS) + ".", ""]
    for heading, model, where, example in SECTIONS:
        _check_example(heading, example)
        doc = " ".join((model.__doc__ or "").split())
        out += [f"## `{heading}`" if heading != "Top level" else "## Top level", "", f"{doc} Where: {where}.", ""]
        if model is models.Scene:
            out += _rows_top()
        else:
            out += _rows(model)
        out += ["", "```toml", example.rstrip("\n"), "```", ""]
    return "\n".join(out)


def _is_table(field) -> bool:
    return any(isinstance(m, type) and issubclass(m, BaseModel) for m in
               (field.annotation, *getattr(field.annotation, "__args__", ())))


def _rows_top() -> list[str]:
    rows = _rows(models.Scene)
    keep = rows[:2]
    for (name, field), row in zip(models.Scene.model_fields.items(), rows[2:]):
        if not _is_table(field):
            keep.append(row)
    keep.append("")
    keep.append("The tables: " + ", ".join(f"`{h}`" for h, _, _, _ in SECTIONS[1:]) + ".")
    return keep


def _anchor(heading: str) -> str:
    return re.sub(r"[^a-z0-9 _-]", "", heading.lower()).replace(" ", "-")


# ------------------------------------------------------------------------------------------------ the CLI
def _commands() -> list[tuple[str, argparse.ArgumentParser, str]]:
    from taichi_rocks.cli import __doc__ as cli_doc
    from taichi_rocks.cliparse import parser as cli_parser

    parser = cli_parser(cli_doc.split("\n")[0])
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {a.dest: a.help for a in sub._choices_actions}
    return [(name, p, helps.get(name, "")) for name, p in sub.choices.items()]


def _usage(name: str, p: argparse.ArgumentParser) -> str:
    parts = [f"taichi-rocks {name}"]
    for a in p._actions:
        if isinstance(a, argparse._HelpAction):
            continue
        if not a.option_strings:
            parts.append(a.metavar or a.dest.upper() + ("..." if a.nargs == "+" else ""))
            if a.nargs == "+":
                parts[-1] += " ..."
            continue
        flag = a.option_strings[-1]
        arg = "" if a.nargs == 0 else " " + _metavar(a)
        parts.append(f"{flag}{arg}" if a.required else f"[{flag}{arg}]")
    return " ".join(parts)


def _metavar(a) -> str:
    if a.metavar:
        return a.metavar
    if a.choices:
        return "{" + ",".join(map(str, a.choices)) + "}"
    return a.dest.upper()


def cli_page() -> str:
    out = ["# Command line", "",
           "`taichi-rocks COMMAND ...` (or `python -m taichi_rocks COMMAND ...`). Exit status: 0 done, 1 the "
           "simulation went wrong (the runtime guard; `sweep`: a run failed), 2 bad input (one line naming the file "
           "and the key, nothing written), 130 interrupted: [robustness.md](robustness.md).", "",
           "*Generated from the argument parser (`taichi_rocks/cliparse.py`) by `python tools/gen_docs.py`; "
           "tests/test_gen_docs.py checks that it is current.*", ""]
    for name, p, what in _commands():
        out += [f"## {name}", "", what[0].upper() + what[1:] + ".", "", "```", _usage(name, p), "```", ""]
        rows = []
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            flags = ", ".join(a.option_strings) or (a.metavar or a.dest.upper())
            value = "" if a.nargs == 0 or not a.option_strings else _metavar(a)
            default = "" if a.default in (None, False) or not a.option_strings else f"`{a.default}`"
            rows.append(f"| `{flags}` | {_cell(value)} | {default} | {_cell(a.help or '')} |")
        if rows:
            out += ["| argument | value | default | what |", "|---|---|---|---|", *rows, ""]
    return "\n".join(out)


def commands_block() -> str:
    rows = ["| command | what it does |", "|---|---|"]
    for name, p, what in _commands():
        positional = " ".join(a.metavar or a.dest.upper() for a in p._actions if not a.option_strings
                              and not isinstance(a, argparse._HelpAction))
        rows.append(f"| `taichi-rocks {name}{' ' + positional if positional else ''}` | {_cell(what)} |")
    return "\n".join(rows)


# ------------------------------------------------------------------------------------------------ the viewer
def view_keys_block() -> str:
    from taichi_rocks.app.view import DRIVE_KEYS, KEYS

    rows = ["| key | does |", "|---|---|"]
    rows += [f"| {label} | {_cell(does)} |" for _, label, does in KEYS + DRIVE_KEYS]
    return "\n".join(rows)


def view_sliders_block() -> str:
    from taichi_rocks.engine.params import SLIDERS

    rows = ["| slider | scene key | from | to |", "|---|---|---|---|"]
    rows += [f"| {label} | `{key}` | {_number(float(lo))} | {_number(float(hi))} |"
             for key, (label, lo, hi) in SLIDERS.items()]
    return "\n".join(rows)


RECORDS_INTRO = """# Records

<!-- Generated by tools/gen_docs.py from the records' declarations (config/records.py); do not edit by hand. -->

What the simulation hands out, field by field. Each record is a dataclass: read a field as an attribute
(`st.positions`) or as the dict key it has always had (`st["positions"]`, `"orientations" in st`);
`as_dict()` gives the plain dict (the `.npz` writers take it, and `np.savez(path, **st)` works on the record
itself). A field marked *optional* is None, and absent from the dict, when the simulation does not make it
(tumbling's arrays without tumbling, the rocks of `state(rocks=False)`). Units: `-` a code, a flag or a
dimensionless quantity; empty for counts, indices and names. World coordinates are float64 metres, z up.
"""


def records_page() -> str:
    from taichi_rocks.config.records import describe
    from taichi_rocks.engine.records import RECORDS as ENGINE_RECORDS
    from taichi_rocks.output.export import ExportFrame

    out = [RECORDS_INTRO]
    for cls in (*ENGINE_RECORDS, ExportFrame):
        doc = " ".join((cls.__doc__ or "").split()).replace("``", "`")
        out += [f"## {cls.__name__}", "", f"`{cls.__module__}.{cls.__name__}`: {doc}", "",
                "| field | unit | what it is |", "|---|---|---|"]
        for name, unit, text, optional in describe(cls):
            out.append(f"| `{name}` | {unit} | {_cell(text)}{' *(optional)*' if optional else ''} |")
        out.append("")
    return "\n".join(out)


# ------------------------------------------------------------------------------------------------ writing
def replace_block(text: str, name: str, body: str, where: str) -> str:
    """``text`` with the block ``name`` replaced by ``body``; a block missing or present twice is an error."""
    pattern = re.compile(rf"(<!-- generated:{re.escape(name)} -->\n)(?:.*?\n)?(<!-- /generated:{re.escape(name)} -->)",
                         re.S)
    found = len(pattern.findall(text))
    if found != 1:
        raise ValueError(f"{where}: block generated:{name} found {found} times (expected once)")
    return pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)


def pages() -> dict[Path, str]:
    """Each generated page's path and the text it should have."""
    out = {SCENE_FORMAT: scene_format(), CLI: cli_page(), RECORDS: records_page()}
    readme = README.read_text()
    out[README] = replace_block(readme, "commands", commands_block(), "README.md")
    rendering = RENDERING.read_text()
    rendering = replace_block(rendering, "view-keys", view_keys_block(), "docs/rendering.md")
    out[RENDERING] = replace_block(rendering, "view-sliders", view_sliders_block(), "docs/rendering.md")
    return out


def stale() -> list[Path]:
    return [p for p, text in pages().items() if not p.exists() or p.read_text() != text]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only compare; exit 1 if a page differs")
    args = ap.parse_args(argv)
    wanted = pages()
    differ = [p for p, text in wanted.items() if not p.exists() or p.read_text() != text]
    if args.check:
        for p in differ:
            print(f"{p.relative_to(ROOT)}: differs from the code (run python tools/gen_docs.py)", file=sys.stderr)
        return 1 if differ else 0
    for p in differ:
        p.write_text(wanted[p])
        print(f"{p.relative_to(ROOT)}: written")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
