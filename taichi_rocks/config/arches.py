"""The Taichi backends a user can ask for, by name (no Taichi here: the command line imports it to list
them). ``gpu`` means CUDA; see taichi_rocks/engine/runtime.py for what each one starts.

``precision = "f64"`` does not run on Vulkan: Taichi 1.7.4's SPIR-V code generator has no 64-bit trigonometric
functions (the tread model's asin fails to compile: "Instruction Asin(16) does not 64bits operation"), so
:func:`precision_problem` refuses it before anything starts.

``[sim.hash] insert = "aabb"`` gives wrong answers on Vulkan: there it inserts each rock into every cell of
its box in a loop of atomics, and Taichi 1.7.4's Vulkan backend (lavapipe) loses some of those updates, so
tires miss rocks (30 frames of minimal.toml with 8,000 rocks: 157 launches against the CPU's 251).
:func:`insert_problem` refuses it; centre insertion (the default) gives the CPU's answer there.
:func:`arch_problem` is the first of the two: the command line asks it before anything is written (``--arch``), and
``Simulation`` (engine/simulation.py) before Taichi starts and again with the backend Taichi runs on (``arch=``),
so the Python API refuses what the command line refuses, with the same words."""

from .presets import PRESETS

ARCHES = ("cpu", "gpu", "cuda", "vulkan")
NO_F64 = ("vulkan",)  # backends that cannot compile the engine's f64 kernels
NO_AABB = ("vulkan",)  # backends whose aabb insertion loses rocks


CLI, API = "--arch {}", 'arch="{}"'  # how the backend is named in a message: the option, or Simulation's argument


def precision_problem(scene, arch: str, how: str = CLI):
    """The one-line error (``FILE: sim.precision: ...``) when ``scene`` asks for a precision that ``arch``
    cannot run, else None. ``how``: :data:`CLI` or :data:`API`, how the message names the backend."""
    if arch not in NO_F64 or scene.sim.precision != "f64":
        return None
    preset = PRESETS.get(scene.sim.accuracy, {})
    why = f' (sim.accuracy = "{scene.sim.accuracy}" sets it)' if preset.get("precision") == "f64" else ""
    return (f'{scene.source}: sim.precision: "f64"{why} cannot run with {how.format(arch)} (Taichi\'s {arch} '
            f'backend has no 64-bit trigonometry); use {how.format("cpu")} or {how.format("cuda")}, or '
            f'precision = "f32"')


def insert_problem(scene, arch: str, how: str = CLI):
    """The one-line error (``FILE: sim.hash.insert: ...``) when ``scene`` hashes rocks by their boxes on a
    backend that loses such insertions, else None. ``how``: as for :func:`precision_problem`."""
    if arch not in NO_AABB or scene.sim.hash.insert != "aabb":
        return None
    return (f'{scene.source}: sim.hash.insert: "aabb" gives wrong answers with {how.format(arch)} (its backend '
            f'loses some of the box insertions, so tires miss rocks); use insert = "center" (the default) or '
            f'{how.format("cpu")} or {how.format("cuda")}')


def arch_problem(scene, arch: str, how: str = CLI):
    """The first reason ``arch`` cannot run ``scene`` (:func:`precision_problem`, :func:`insert_problem`), or
    None."""
    return precision_problem(scene, arch, how) or insert_problem(scene, arch, how)
