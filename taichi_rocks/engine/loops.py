"""How the top-level loops of a step's kernels run: in parallel over the thread pool, or one after another on
the launching thread (the step's *serial variant*).

Taichi runs each top-level loop of a kernel as a task of its own; on its CPU backend a parallel task wakes the
thread pool and waits for it, some 55 us before any work with 1 or 2 threads (docs/performance.md, "What a
task costs"), while a serial loop costs a few microseconds. A game's step visits a few thousand rocks in about
ten such loops, so on a few cores the pool costs more than the work it shares out; on a GPU a serial loop runs
on one thread, 15-90x slower than a CPU core. Each step kernel therefore compiles in two variants, chosen from
the host (engine/variant.py): the kernel's switches carry ``serial`` (engine/kernels.py ``Switches``), and
every loop of the step that scales with the rocks or the hash is preceded by :func:`top_loop`. Both variants
compute the same rocks, launches and events: every per-rock result is independent of the thread order (claims
decide which tire wins a rock, engine/tires.py); only the order of the active list in memory differs, which
``state()`` (by id) hides.
"""

import taichi as ti


@ti.func
def top_loop(plan: ti.template()):
    """Right before a top-level loop of a step kernel: the loop runs serially in the serial variant
    (``plan.serial``), in parallel otherwise. ``plan``: the kernel's Switches, or None (a kernel without
    variants: parallel). In the serial variant Taichi fuses the kernel's loops into one serial task."""
    if ti.static(getattr(plan, "serial", False)):
        ti.loop_config(serialize=True)
