"""taichi_rocks: a bed of rocks that follows the player vehicle while the rear tires of vehicles
launch rocks into the air (Chen, Fu & Wegman 1999), simulated with Taichi and driven by TOML scenes."""

import os as _os

# Taichi prints a banner on stdout when imported; keep stdout for results (set before taichi is imported).
_os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")

__version__ = "0.1.0"
