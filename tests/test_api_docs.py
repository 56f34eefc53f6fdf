"""The public API documents its arguments: ``help(taichi_rocks.Simulation)`` reads as a manual. Every function of
the public face and every public method of Simulation names each of its parameters under "Args:" and, when it
returns something, says what under "Returns:"; every property has a docstring. A new parameter or method without
them fails here."""

import inspect
import re

import taichi_rocks

FUNCTIONS = ("load_scene", "scene_with", "record", "load_run", "render_scene", "run_sweep")
CLASSES = ("Simulation", "Renderer")  # their constructors' arguments in the class docstring


def _section(doc: str, title: str) -> str:
    m = re.search(rf"^\s*{title}:\n((?:\s+.*\n?|\n)*?)(?=^\s*[A-Z][a-z]+:\n|\Z)", doc, re.M)
    return m.group(1) if m else ""


def _documented(doc: str) -> set:
    """Names the Args section introduces: ``name:`` or ``a, b, c:`` at the start of an entry."""
    names = set()
    for line in _section(doc, "Args").splitlines():
        m = re.match(r"\s{4,8}(\*{0,2}[a-z_][a-z_0-9]*(?:, [a-z_][a-z_0-9]*)*):", line)
        if m:
            names.update(n.lstrip("*") for n in m.group(1).split(", "))
    return names


def _params(fn) -> list:
    return [p.name for p in inspect.signature(fn).parameters.values() if p.name not in ("self", "cls")]


def _check(name: str, fn, doc: str, returns: bool) -> list:
    problems = []
    doc = inspect.cleandoc(doc or "") + "\n"
    missing = set(_params(fn)) - _documented(doc)
    if missing:
        problems.append(f"{name}: Args lacks {sorted(missing)}")
    if returns and not _section(doc, "Returns").strip():
        problems.append(f"{name}: no Returns")
    return problems


def _returns_something(fn) -> bool:
    ann = inspect.signature(fn).return_annotation
    return ann not in (None, "None", inspect.Signature.empty)


def test_the_public_functions_document_their_arguments_and_results():
    problems = []
    for name in FUNCTIONS:
        fn = getattr(taichi_rocks, name)
        problems += _check(name, fn, fn.__doc__, returns=True)
    for name in CLASSES:
        cls = getattr(taichi_rocks, name)
        problems += _check(name, cls.__init__, cls.__doc__, returns=False)
    assert problems == []


def _members(cls) -> dict:
    """Every member a class defines or takes from its project bases (Simulation's mixins: engine/simreads.py,
    engine/simsaves.py), the class's own winning."""
    out = {}
    for base in reversed(cls.__mro__):
        if base.__module__.startswith("taichi_rocks"):
            out.update(vars(base))
    return out


def test_every_public_member_of_simulation_is_documented():
    sim = taichi_rocks.Simulation
    problems, methods = [], 0
    for name, member in _members(sim).items():
        if name.startswith("_"):
            continue
        if isinstance(member, property):
            if not (member.fget.__doc__ or "").strip():
                problems.append(f"Simulation.{name}: no docstring")
            continue
        fn = member.__func__ if isinstance(member, classmethod) else member
        if not callable(fn):
            continue
        methods += 1
        problems += _check(f"Simulation.{name}", fn, fn.__doc__, returns=_returns_something(fn))
    assert methods >= 12 and problems == []


def test_the_check_finds_an_undocumented_argument():
    def f(a, b):
        """Does it.

        Args:
            a: one.

        Returns:
            Something.
        """

    assert _check("f", f, f.__doc__, returns=True) == ["f: Args lacks ['b']"]
    assert _check("f", f, "Does it.\n\nArgs:\n    a, b: both.\n", returns=True) == ["f: no Returns"]
