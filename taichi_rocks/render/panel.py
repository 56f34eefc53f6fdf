"""The view's panel and HUD: GGUI (Dear ImGui) widgets drawn over the picture, in two sub-windows.

* "taichi-rocks" (bottom left): the HUD (driving with --drive: the vehicle's speed; time and frame, playing or paused and the speed, frames per second
  shown, rocks in the air, launches, the camera; with impacts on or hits seen, the player's hits by damage
  class, render/hits.py; notices such as "recompiling") and the time slider;
* "tune" (right): the runtime parameters as sliders (engine/tuning.py SLIDERS, from engine/params.py; they act
  at once; a [min, max] pair gets two), the switches that need a recompile (``v.switch_choices``: engine/tuning.py
  SWITCH_KEYS and the impacts, app/view.py VIEW_SWITCHES) as buttons that step through their choices, the cameras as buttons (the scene's shots, if it has any, then the
  presets; ``v.cameras``) and the overlays as check boxes.

Widgets only read the viewer and return what the user changed (:class:`Changes`); the viewer applies it.
The first widget of "tune" is the wetness slider, a fixed place the tests drag with the mouse.
"""

from dataclasses import dataclass, field

from ..engine.tuning import SLIDERS

__all__ = ["SLIDERS", "Changes", "draw_panel", "hud_lines", "panel_width"]

OVERLAYS = (("bed_edge", "bed edge"), ("tire_rays", "tire rays"), ("hash_cells", "hash cells"),
            ("tread_patch", "tread patch"))
PANEL_PX = 300  # width of "tune" in pixels (at most 45% of the window)
HUD_PX = 190  # height of "taichi-rocks" in pixels (up to seven lines and the time slider)


@dataclass
class Changes:
    """What the user changed in the panel this frame."""

    seek: int = None  # frame to go to
    runtime: dict = field(default_factory=dict)  # runtime key -> value
    switch: tuple = None  # (key, value) of a switch
    view: str = None  # camera preset (or "free")
    overlays: dict = field(default_factory=dict)


def panel_width(width: int) -> float:
    return min(0.45, PANEL_PX / float(width))


def hud_lines(v) -> list:
    """The HUD's lines for viewer ``v``."""
    tl = v.timeline
    state = "playing" if tl.playing else "paused"
    lines = [f"t {tl.time:7.2f} s   frame {tl.frame} / {tl.frames - 1}",
             f"{state} x{tl.speed:g}   {v.fps:5.1f} fps",
             f"in the air {v.in_air}   launches {v.sim.launches_total}",
             f"camera {v.camera_name}"]
    d = getattr(v, "driving", None)
    if d is not None:  # app/driving.py: the vehicle the keys drive
        lines.insert(0, f"driving {d.name}: {abs(d.speed) * 3.6:4.0f} km/h{' reverse' if d.speed < 0 else ''}"
                        f"   (W/S/A/D)")
    hits = v.renderer.hits
    if v.switches.get("effects.impacts") or len(hits.hits.events):
        n = hits.counts()
        lines.append("hits on the player  " + "   ".join(f"{c} {k}" for c, k in n.items()))
    if v.notice:
        lines.append(v.notice)
    return lines


def draw_panel(gui, v) -> Changes:
    """Declare both sub-windows for viewer ``v``; return the changes."""
    ch = Changes()
    w_px, h_px = v.resolution
    pw = panel_width(w_px)
    hh = min(0.5, HUD_PX / float(h_px))
    with gui.sub_window("taichi-rocks", 0.0, 1.0 - hh, 1.0 - pw, hh) as w:
        for line in hud_lines(v):
            w.text(line, color=(1.0, 0.85, 0.3) if v.notice and line == v.notice else None)
        tl = v.timeline
        t = w.slider_float("time s", tl.time, 0.0, (tl.frames - 1) / tl.fps)
        if abs(t - tl.time) * tl.fps >= 0.5:
            ch.seek = int(round(t * tl.fps))
    with gui.sub_window("tune", 1.0 - pw, 0.0, pw, 1.0) as w:
        _sliders(w, v, ch)
        w.text("recompile:")
        for key, choices in v.switch_choices.items():
            cur = v.switches[key]
            if w.button(f"{key.rsplit('.', 1)[-1]}: {_word(cur)}"):
                ch.switch = (key, choices[(choices.index(cur) + 1) % len(choices)])
        w.text("camera (c cycles, f free):")
        for name in tuple(v.cameras) + ("free",):
            if w.button(("> " if v.camera_name == name else "  ") + name):
                ch.view = name
        w.text("overlays:")
        for flag, label in OVERLAYS:
            cur = bool(getattr(v.renderer.flags, flag))
            new = w.checkbox(label, cur)
            if new != cur:
                ch.overlays[flag] = new
    return ch


def _sliders(w, v, ch: Changes) -> None:
    values = v.runtime
    for key, (label, lo, hi) in SLIDERS.items():
        cur = values[key]
        if isinstance(cur, (list, tuple)):  # a [min, max] pair
            a = w.slider_float(f"{label} min", float(cur[0]), lo, hi)
            b = w.slider_float(f"{label} max", float(cur[1]), lo, hi)
            if _moved(a, cur[0], lo, hi) or _moved(b, cur[1], lo, hi):
                ch.runtime[key] = [min(a, b), b] if _moved(a, cur[0], lo, hi) else [a, max(a, b)]
            continue
        new = w.slider_float(label, float(cur), lo, hi)
        if _moved(new, cur, lo, hi):
            ch.runtime[key] = new


def _moved(new: float, old: float, lo: float, hi: float) -> bool:
    """A slider hands back its value as f32: a change is one of more than that rounding."""
    return abs(float(new) - float(old)) > 1e-6 * (hi - lo)


def _word(value) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    return str(value)
