"""The accuracy presets of `[sim] accuracy` (no Taichi)."""

# From the measured study of `taichi-rocks bench` (README, "Accuracy
# against cost"): the cheapest settings meeting a flight error over a 2 s flight of 5 cm / 1 mm / 1 um, a
# recall of the true tire contacts at 60 m/s of at least 0.9 / 0.99 / 0.999, and a launch-time error bound
# v_launch * dt of 0.6 m / 6 cm / 6 mm. Keys written in the file override the preset's.
PRESETS = {
    "draft": {"dt": 0.02, "integrator": "heun", "detection": "swept", "precision": "f32"},
    "balanced": {"dt": 0.002, "integrator": "heun", "detection": "swept", "precision": "f32"},
    "reference": {"dt": 0.0002, "integrator": "heun", "detection": "swept", "precision": "f64"},
}
