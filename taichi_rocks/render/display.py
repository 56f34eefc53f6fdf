"""Is there a screen to open a window on? Asked before Taichi is imported, so that ``taichi-rocks view``
without a display fails at once with one line (no Taichi start-up, no GGUI exception)."""

import ctypes
import os

__all__ = ["display_problem", "NO_DISPLAY_HINT"]

NO_DISPLAY_HINT = "`taichi-rocks render SCENE` draws the same pictures offscreen, to frames and a video"


def display_problem():
    """None if an X display can be opened; else why not, in a few words. Without Xlib to ask (not an X
    system), only DISPLAY (or WAYLAND_DISPLAY) is checked."""
    name = os.environ.get("DISPLAY")
    if not name:
        if os.environ.get("WAYLAND_DISPLAY"):
            return None
        return "no display (DISPLAY is not set)"
    try:
        xlib = ctypes.CDLL("libX11.so.6")
    except OSError:
        return None
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    dpy = xlib.XOpenDisplay(name.encode())
    if not dpy:
        return f"cannot open display {name!r}"
    xlib.XCloseDisplay(dpy)
    return None
