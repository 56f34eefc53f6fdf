"""What the frames look like: colours and lights, in linear RGB as GGUI shades them
(colour * (ambient + sum of Lambert terms)). No Taichi here."""

AMBIENT = (0.40, 0.42, 0.46)
SUN_COLOR = (0.68, 0.66, 0.60)
SUN_DIR_CAMERA = (-0.45, 0.55, 1.0)  # sun direction in the camera-heading frame (x fwd, y left, z up)
GROUND_A = (0.56, 0.53, 0.44)
GROUND_B = (0.49, 0.46, 0.38)
HAZE = 2.5  # draw distances: e-folding distance of the ground's haze
HORIZON_BLEND = 0.45  # the horizon's colour: the sky's, this far towards white
TIRE_COLOR = (0.09, 0.09, 0.10)
TREAD_COLOR = (0.20, 0.20, 0.21)  # every other tread block
HUB_COLOR = (0.62, 0.62, 0.64)  # the rim's spokes and cap
RIM_DARK_COLOR = (0.14, 0.14, 0.15)  # the openings between the spokes
HEADLIGHT_COLOR = (0.98, 0.96, 0.85)
PLAYER_MARK_COLOR = (0.97, 0.97, 0.95)  # the player's stripes and side bands
GLASS_COLOR = (0.24, 0.31, 0.40)
TAIL_LIGHT_COLOR = (1.0, 0.55, 0.35)
BUMPER_COLOR = (0.13, 0.13, 0.14)
PILLAR_COLOR = (0.16, 0.16, 0.17)  # the windscreen's frame, seen from the driver's seat (render/interior.py)
HEADLINER_COLOR = (0.52, 0.51, 0.49)  # the roof's lining
DASHBOARD_COLOR = (0.11, 0.11, 0.12)
BED_EDGE_COLOR = (1.0, 0.85, 0.1)
RAY_COLOR = (1.0, 0.1, 0.1)
CELL_COLOR = (0.1, 0.9, 1.0)
PATCH_COLOR = (0.2, 1.0, 0.3)  # the tread's contact patch
KEY = (3, 251, 5)  # GGUI's clear colour, 8-bit: where the read-back has it, the background image shows


def rgb(c) -> tuple:
    """A colour as three floats in [0, 1]: from "#rrggbb" or from three numbers."""
    if isinstance(c, str):
        c = tuple(int(c[i:i + 2], 16) / 255 for i in (1, 3, 5))
    return tuple(float(x) for x in c)


def horizon_color(sky) -> tuple:
    """The colour the sky lightens to at the horizon and the ground's haze fades to."""
    return tuple(float(c + (1.0 - c) * HORIZON_BLEND) for c in sky)
