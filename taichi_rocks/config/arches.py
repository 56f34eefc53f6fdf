"""The Taichi backends a user can ask for, by name (no Taichi here: the command line imports it to list
them). ``gpu`` means CUDA; see taichi_rocks/engine/runtime.py for what each one starts.

``precision = "f64"`` does not run on Vulkan: Taichi 1.7.4's SPIR-V code generator has no 64-bit trigonometric
functions (the tread model's asin fails to compile: "Instruction Asin(16) does not 64bits operation"), so
:func:`precision_problem` refuses it before anything starts."""

from .presets import PRESETS

ARCHES = ("cpu", "gpu", "cuda", "vulkan")
NO_F64 = ("vulkan",)  # backends that cannot compile the engine's f64 kernels


def precision_problem(scene, arch: str):
    """The one-line error (``FILE: sim.precision: ...``) when ``scene`` asks for a precision that ``arch``
    cannot run, else None."""
    if arch not in NO_F64 or scene.sim.precision != "f64":
        return None
    preset = PRESETS.get(scene.sim.accuracy, {})
    why = f' (sim.accuracy = "{scene.sim.accuracy}" sets it)' if preset.get("precision") == "f64" else ""
    return (f'{scene.source}: sim.precision: "f64"{why} cannot run with --arch {arch} (Taichi\'s {arch} backend '
            f'has no 64-bit trigonometry); use --arch cpu or cuda, or precision = "f32"')
