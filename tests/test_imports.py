"""The package's imports, read from its source with ``ast`` (nothing is imported): no circles; imports at the
top of modules (only cli.py, for its start-up time, and optional dependencies import inside functions); the
rooms' rules of docs/architecture.md; and its may-import table equal to the imports that exist.

Two registries load modules by name on purpose and are not seen here: the package's public API
(taichi_rocks/__init__.py ``_API``, imported on first use so that ``import taichi_rocks`` stays cheap) and the
export formats (output/formats.py ``FORMATS``: a writer's module is imported when it is used).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "taichi_rocks"
ARCHITECTURE = ROOT / "docs" / "architecture.md"
# folders; "cli" is cli.py, cliparse.py, __main__.py
ROOMS = ("config", "motion", "engine", "output", "render", "bench", "app", "runner")
# optional dependencies (extras, or only there for a study): the only imports allowed inside functions
OPTIONAL = {"pxr", "matplotlib", "warp", "ray", "PIL", "jsonschema", "hypothesis"}
# what an engine object is called outside engine/ (a Simulation, its World)
ENGINE_NAMES = {"sim", "simulation", "world"}

# Today's known exceptions to "only engine/ touches the engine's insides": (file, expression) -> why it is
# still there. The list must shrink: remove an entry when its code goes (test_engine_insides_allow_list_is_current
# fails until then), never add one.
ENGINE_INSIDES_ALLOWED: dict = {}  # none left: the renderer reads the engine through engine/drawing.py


# ------------------------------------------------------------------------------------------------ reading
def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {_module_name(p): p for p in sorted(PKG.rglob("*.py"))}
TREES = {name: ast.parse(path.read_text(), str(path)) for name, path in MODULES.items()}


def _package(name: str) -> str:
    return name if MODULES[name].name == "__init__.py" else name.rpartition(".")[0]


def _targets(module: str, node) -> list[str]:
    """The absolute module names an import statement names (``from . import active``: the module active)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    base = node.module or ""
    if node.level:
        pkg = _package(module).split(".")
        pkg = pkg[:len(pkg) - node.level + 1]
        base = ".".join(pkg + ([node.module] if node.module else []))
    subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES]
    return subs or [base]


def _imports(module: str):
    """(node, target modules, inside a function or class) for every import statement of ``module``."""
    out = []

    def walk(node, nested):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                out.append((child, _targets(module, child), nested))
            walk(child, nested or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda,
                                                     ast.ClassDef)))

    walk(TREES[module], False)
    return out


def _internal(target: str) -> list[str]:
    """The package's modules an import of ``target`` runs: the module and the packages above it."""
    parts = target.split(".")
    return [m for m in (".".join(parts[:k]) for k in range(2, len(parts) + 1)) if m in MODULES]


def import_graph() -> dict[str, set]:
    graph = {m: set() for m in MODULES}
    for m in MODULES:
        for _, targets, _ in _imports(m):
            for t in targets:
                graph[m].update(x for x in _internal(t) if x != m and not m.startswith(x + "."))
    return graph


def room_of(module: str):
    parts = module.split(".")
    if len(parts) >= 2 and parts[1] in ROOMS:
        return parts[1]
    if module in ("taichi_rocks.cli", "taichi_rocks.cliparse", "taichi_rocks.__main__"):
        return "cli"
    return None  # taichi_rocks/__init__.py: the lazy public API


def _rel(module: str) -> str:
    return str(MODULES[module].relative_to(PKG))


# ------------------------------------------------------------------------------------------------ (a) circles
def _cycles(graph: dict) -> list[list[str]]:
    """Every strongly connected component of more than one module (Tarjan), each as a list of modules."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_reader_sees_the_imports():
    graph = import_graph()
    assert "taichi_rocks.engine.simulation" in graph["taichi_rocks.app.simulate"]
    assert "taichi_rocks.engine.rocks" in graph["taichi_rocks.engine.simulation"]  # from . import rocks
    assert "taichi_rocks.app.render" in graph["taichi_rocks.cli"]  # a function-local import counts too
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circles():
    assert _cycles(import_graph()) == []


# ------------------------------------------------------------------------------------------------ (b) top
def test_imports_sit_at_the_top_except_in_cli_and_for_optional_dependencies():
    found = []
    for m in MODULES:
        if room_of(m) == "cli":
            continue
        for node, targets, nested in _imports(m):
            if nested and not all(t.split(".")[0] in OPTIONAL for t in targets):
                found.append(f"{_rel(m)}:{node.lineno}: {ast.unparse(node)}")
    assert found == []


# ------------------------------------------------------------------------------------------------ (c) rooms
def _room_imports() -> dict:
    """room -> {room or top-level external package: [(file, line)]}, every import of the room's modules."""
    out = {}
    for m in MODULES:
        room = room_of(m)
        if room is None:
            continue
        for node, targets, _ in _imports(m):
            for t in targets:
                other = room_of(t) if t in MODULES or t.startswith("taichi_rocks.") else t.split(".")[0]
                if other is None and t.startswith("taichi_rocks"):
                    other = "taichi_rocks"
                if other != room:
                    out.setdefault(room, {}).setdefault(other, []).append((_rel(m), node.lineno))
    return out


def test_config_imports_no_taichi_and_no_other_room():
    got = _room_imports().get("config", {})
    assert "taichi" not in got
    assert not set(got) & set(ROOMS + ("cli",))


def test_bench_and_render_never_import_each_other():
    rooms = _room_imports()
    assert "render" not in rooms.get("bench", {}) and "bench" not in rooms.get("render", {})


def engine_insides() -> dict:
    """(file, expression) -> lines, outside engine/: an underscored member of an engine object
    (``sim._x``, ``self.sim._x``, ``world._x``) or a field of the tile store (``world.ts_key``, ...)."""
    found = {}
    for m in MODULES:
        if room_of(m) == "engine":
            continue
        for node in ast.walk(TREES[m]):
            if not isinstance(node, ast.Attribute):
                continue
            owner = node.value.attr if isinstance(node.value, ast.Attribute) else getattr(node.value, "id", None)
            private = node.attr.startswith("_") and not node.attr.startswith("__") and owner in ENGINE_NAMES
            if private or node.attr.startswith("ts_"):
                found.setdefault((_rel(m), ast.unparse(node)), []).append(node.lineno)
    return found


def test_only_engine_touches_the_engine_insides():
    """Outside engine/, an engine object is used through its public face. Known exceptions: the allow-list."""
    found = engine_insides()
    new = {k: v for k, v in found.items() if k not in ENGINE_INSIDES_ALLOWED}
    assert new == {}


def test_engine_insides_allow_list_is_current():
    """An exception that is gone must leave the allow-list, so that the list only shrinks."""
    found = engine_insides()
    gone = [k for k in ENGINE_INSIDES_ALLOWED if k not in found]
    assert gone == [], "remove these from ENGINE_INSIDES_ALLOWED: the code no longer does it"


def test_the_engine_insides_reader_sees_them():
    tree = ast.parse("a = self.sim._tiles\nb = sim.world._x\nc = world.ts_key[i]\nd = sim.__class__\ne = rig._t\n")
    found = {ast.unparse(n) for n in ast.walk(tree) if isinstance(n, ast.Attribute)
             and ((n.attr.startswith("_") and not n.attr.startswith("__")
                   and (n.value.attr if isinstance(n.value, ast.Attribute) else getattr(n.value, "id", None))
                   in ENGINE_NAMES) or n.attr.startswith("ts_"))}
    assert found == {"self.sim._tiles", "sim.world._x", "world.ts_key"}


# ------------------------------------------------------------------------------------------------ (d) table
def rooms_table() -> dict:
    """docs/architecture.md's rooms table: room -> (may import, never), the rooms each cell names."""
    rows = {}
    for line in ARCHITECTURE.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[0].startswith("`"):
            continue
        names = re.findall(r"`([^`]+)`", cells[0])
        room = "cli" if "cli.py" in names else names[0].rstrip("/")
        if room not in ROOMS + ("cli",):
            continue
        named = [set(re.findall(r"\b(" + "|".join(ROOMS) + r")\b", cell)) for cell in cells[2:]]
        rows[room] = (named[0], named[1], cells[3])
    return rows


def test_the_table_has_a_row_per_room():
    assert set(rooms_table()) == set(ROOMS) | {"cli"}


def test_the_may_import_table_lists_the_imports_that_exist():
    table, actual = rooms_table(), _room_imports()
    for room, (may, _, _) in sorted(table.items()):
        imported = {r for r in actual.get(room, {}) if r in ROOMS}
        assert imported - may == set(), f"{room}/ imports these; add them to its row: {sorted(imported - may)}"
        assert may - imported == set(), f"{room}/ does not import these; drop them from its row: {sorted(may - imported)}"


def test_no_room_imports_what_its_row_says_it_never_does():
    table, actual = rooms_table(), _room_imports()
    for room, (_, never, never_text) in table.items():
        got = actual.get(room, {})
        assert not never & set(got), (room, sorted(never & set(got)))
        if "Taichi" in never_text:
            assert "taichi" not in got, (room, got.get("taichi"))
