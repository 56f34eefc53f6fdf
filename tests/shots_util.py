"""A scene with camera shots for the tests of render, view and export, and the camera each must show: the
shots' rigs stepped at the frame times, from the vehicles' scripted poses (motion/ only: no Taichi)."""

import math

import numpy as np

# A car on a circle (heading changing at 1 rad/s, so the chase camera's smoothing matters) with a van driving
# straight beside it. Shots: the [camera] table's chase view of the car until 0.75 s, then the car's driver's
# seat, then from 1.35 s beside the van's rear tires.
SHOTS_SCENE = """name = "{name}"
duration = 2.0
[bed]
radius = 8.0
rocks = 2000
rock_radius = [0.02, 0.05]
[sim]
detection = "patch"
dt = 0.004
[[vehicle]]
name = "car"
path = {{ kind = "circle", center = [0.0, 0.0], radius = 12.0, speed = 12.0 }}
[[vehicle]]
name = "van"
splash = false
length = 5.0
height = 2.0
path = {{ points = [[30.0, 0.0], [60.0, 0.0]], speed = 5.0 }}
[camera]
view = "chase"
[[camera.shot]]
at = 0.75
view = "driver"
[[camera.shot]]
at = 1.35
view = "side"
target = "van"
"""
CUTS = (0.75, 1.35)  # s
VIEWS = ("chase", "driver", "side")  # the shots' views, in order


def write_shots_scene(folder, name="shots"):
    path = folder / f"{name}.toml"
    path.write_text(SHOTS_SCENE.format(name=name))
    return path


def rot(h):
    c, s = math.cos(h), math.sin(h)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def expected_eyes(scene, times):
    """World eye per time (the times in order, from 0: the frame times a camera is stepped at), the shot of
    each, by the rules of docs/scene-format.md written out: before the first cut the chase rig of the car
    (smoothed heading, stepped at every time); the driver's seat fixed to the car (motion/cabin.py eye, turned
    by the car's own heading); beside the van (the side preset; the van drives straight: no smoothing)."""
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.motion.camera import CameraRig, view_preset
    from taichi_rocks.motion.vehicles import Fleet

    fleet = Fleet(scene)
    car, van = scene.vehicles
    chase = CameraRig(view_preset("chase", car, car, scene.camera.look_ahead)[0], scene.camera.look_ahead,
                      scene.camera.smoothing)
    side = view_preset("side", van, van, scene.camera.look_ahead)[0]
    seat = np.array(cabin_of(car).eye)
    eyes, shots = [], []
    for t in times:
        p = fleet.poses(t)
        k = sum(t >= c - 1e-9 for c in CUTS)
        if k == 0:
            eye = chase.update(p[0].position, p[0].heading, t)[0]
        elif k == 1:
            eye = p[0].position + rot(p[0].heading) @ seat
        else:
            eye = p[1].position + rot(p[1].heading) @ side
        eyes.append(eye)
        shots.append(k)
    return np.array(eyes), np.array(shots)
