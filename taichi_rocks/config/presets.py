"""The accuracy presets of `[sim] accuracy` (no Taichi): draft, balanced and reference from the measured study,
game for a game's frame (one step per frame at 60 Hz)."""

# From the measured study of `taichi-rocks bench` (README, "Accuracy
# against cost"): the cheapest settings meeting a flight error over a 2 s flight of 5 cm / 1 mm / 1 um, a
# recall of the true tire contacts at 60 m/s of at least 0.9 / 0.99 / 0.999, and a launch-time error bound
# v_launch * dt of 0.6 m / 6 cm / 6 mm. Keys written in the file override the preset's.
PRESETS = {
    "draft": {"dt": 0.02, "integrator": "heun", "detection": "swept", "precision": "f32"},
    "balanced": {"dt": 0.002, "integrator": "heun", "detection": "swept", "precision": "f32"},
    "reference": {"dt": 0.0002, "integrator": "heun", "detection": "swept", "precision": "f64"},
    # one step per 60 Hz frame: the tread's swept footprint finds every rock the tire ran over in the frame's
    # 1/60 s, and Heun keeps a 2 s flight within millimetres (taichi-rocks bench --only frame measures both)
    "game": {"dt": 1.0 / 60.0, "integrator": "heun", "detection": "patch", "precision": "f32"},
}
