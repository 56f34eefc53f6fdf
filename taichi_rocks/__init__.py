"""taichi_rocks: a bed of rocks that follows the player vehicle while the rear tires of vehicles
launch rocks into the air (Chen, Fu & Wegman 1999), simulated with Taichi and driven by TOML scenes."""

__version__ = "0.1.0"
