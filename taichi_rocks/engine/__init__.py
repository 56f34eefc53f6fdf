"""The simulation on Taichi: runtime start-up, the per-rock fields' declaration (rockfields), the World (fields,
world) and its layout and memory estimate (layout), the pass modules (bed, flight, hashgrid, tires, active),
the kernels a step launches (kernels), the set-up from a Scene (setup), the host side of a step (host), the
stepping modes (steppers), the rocks as NumPy arrays (rocks), Simulation (the public face), what to draw
(drawing) and the probes of the benchmark. The only package that writes fields."""

from . import frontend

frontend.install_decorators()  # before any kernel of the package is decorated (engine/frontend.py)
