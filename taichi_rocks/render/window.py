"""The GGUI windows a renderer draws into, one at a time: a hidden one (``render``: the frame is read back) or
one shown on the screen (``view``: the frame is presented).

GGUI draws through Vulkan; on a machine without a GPU, Mesa's software driver (lavapipe) does the work.
GGUI 1.7.4 quirks handled here: never ``window.show()`` on a hidden window (segfault); destroying a window
after others were created and destroyed since segfaults, so only one window is open at a time; a 3D scene
leaks ~0.3 MB per captured frame on lavapipe, so the renderer recreates its window every so many frames, and
each new window gives freed heap memory back to the OS (:func:`_trim_heap`).
"""

import ctypes
from pathlib import Path

import taichi as ti

__all__ = ["VULKAN_HINT", "ggui", "HiddenWindow", "ShownWindow", "trim_heap"]

VULKAN_HINT = ("GGUI needs Vulkan: install Mesa's software driver with "
               "`apt-get install -y mesa-vulkan-drivers libvulkan1`")

_LIBC = []
_LIVE = [None]  # the HiddenWindow that is open (one at a time)


def ggui(make, *args, **kwargs):
    """Create a GGUI object; a missing Vulkan driver becomes one RuntimeError line saying what to install."""
    try:
        return make(*args, **kwargs)
    except Exception as e:  # RuntimeError("Vulkan must be available for GGUI"), GGUINotAvailableException
        if "vulkan" in str(e).lower() or "ggui" in str(e).lower():
            raise RuntimeError(VULKAN_HINT) from None
        raise


def _trim_heap() -> None:
    """Give freed heap memory back to the OS (glibc ``malloc_trim``). A destroyed GGUI window frees its
    Vulkan memory, but into a fragmented heap (a float read-back buffer per frame, lavapipe's JIT): without
    this, RSS still climbs by ~50 MB steps every few window re-creations; with it, ~5 MB per 100 frames."""
    if not _LIBC:
        try:
            libc = ctypes.CDLL("libc.so.6")
            _LIBC.append(libc.malloc_trim)
        except (OSError, AttributeError):  # not glibc
            _LIBC.append(None)
    if _LIBC[0] is not None:
        _LIBC[0](0)


trim_heap = _trim_heap  # for windows that are never recreated (app/view.py)


class HiddenWindow:
    """A hidden ``resolution`` GGUI window with its canvas and scene, opened on demand.

    Opening one closes any other :class:`HiddenWindow` first (its owner reopens it when it next draws:
    check :attr:`is_open`). GGUI's Dear ImGui layer saves its window settings to ./imgui.ini every few
    seconds: :meth:`release` removes that file if it was not there when this object was made.
    """

    shown = False  # the renderer reads the frame back (and merges the background there)

    def __init__(self, resolution):
        self.resolution = tuple(resolution)
        self.window = self.canvas = self.scene = None
        self._imgui_ini = Path.cwd() / "imgui.ini"
        self._imgui_ini_existed = self._imgui_ini.exists()

    @property
    def is_open(self) -> bool:
        return self.window is not None

    def open(self) -> None:
        other = _LIVE[0]
        if other is not None and other is not self:
            other.close()
        self.window = self._make()
        self.canvas = self.window.get_canvas()
        self.scene = self.window.get_scene()
        _LIVE[0] = self
        _trim_heap()

    def _make(self):
        return ggui(ti.ui.Window, "taichi-rocks", self.resolution, show_window=False, vsync=False)

    def close(self) -> None:
        if self.window is not None:
            try:
                self.window.destroy()
            except Exception:  # already gone
                pass
        self.window = self.canvas = self.scene = None
        if _LIVE[0] is self:
            _LIVE[0] = None

    def release(self) -> None:
        """Close the window and remove the imgui.ini GGUI left behind."""
        self.close()
        if not self._imgui_ini_existed:
            try:
                self._imgui_ini.unlink()
            except OSError:
                pass


class ShownWindow(HiddenWindow):
    """An on-screen ``resolution`` GGUI window named ``title``: the renderer declares the background image
    (``canvas.set_image``) and the 3D scene in it and reads nothing back; its owner adds the panel and calls
    ``window.show()`` (which only a shown window may do). It is never recreated: that would flash on the
    screen (see app/view.py for its memory)."""

    shown = True

    def __init__(self, resolution, title: str = "taichi-rocks"):
        super().__init__(resolution)
        self.title = str(title)

    def _make(self):
        return ggui(ti.ui.Window, self.title, self.resolution, show_window=True, vsync=False)

    @property
    def running(self) -> bool:
        """False once the user closed the window."""
        return self.window is not None and bool(self.window.running)
