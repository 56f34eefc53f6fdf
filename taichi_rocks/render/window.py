"""The GGUI windows a renderer draws into, one at a time: a hidden one (``render``: the frame is read back) or
one shown on the screen (``view``: the frame is presented).

GGUI draws through Vulkan; on a machine without a GPU, Mesa's software driver (lavapipe) does the work.
GGUI 1.7.4 quirks handled here: never ``window.show()`` on a hidden window (segfault); destroying a window
after others were created and destroyed since segfaults, so only one window is open at a time; a 3D scene
leaks ~0.3 MB per captured frame on lavapipe, so the renderer recreates its window every so many frames, and
each new window gives freed heap memory back to the OS (:func:`_trim_heap`).

Dear ImGui, under GGUI, reads and writes its layout file ``imgui.ini`` in the current folder (its
``io.IniFilename``, which Taichi does not expose): it replaced a user's own ``imgui.ini`` wherever a render was
started. Each new window's ImGui context is pointed elsewhere (:func:`_place_imgui_ini`): a hidden window keeps
no layout file, the shown one (``view``) keeps its panel's layout in the per-user configuration folder
(:func:`layout_file`: ``$XDG_CONFIG_HOME/taichi-rocks/imgui.ini``, by default under ``~/.config``). The setting
is found through the symbol table of Taichi's library (the context pointer ``GImGui``) and written only where
it holds the default name; where that fails, the window falls back to removing a file it created.
"""

import ctypes
import mmap
import os
import struct
from pathlib import Path

import numpy as np
import taichi as ti
from taichi._lib.core import taichi_python as _taichi_core

__all__ = ["VULKAN_HINT", "ggui", "HiddenWindow", "ShownWindow", "trim_heap", "layout_file"]

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


def layout_file() -> Path:
    """Where the viewer keeps its panel layout: ``$XDG_CONFIG_HOME/taichi-rocks/imgui.ini`` (default
    ``~/.config/taichi-rocks/imgui.ini``)."""
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "taichi-rocks" / "imgui.ini"


_ELF_SYM = np.dtype([("name", "<u4"), ("info", "u1"), ("other", "u1"), ("shndx", "<u2"), ("value", "<u8"),
                     ("size", "<u8")])
_GIMGUI = []  # the runtime address of Dear ImGui's context pointer in Taichi's library, once found (or None)
_KEEP = []  # the C strings handed to ImGui: alive as long as the process
_INI_OFFSET = 32  # io.IniFilename in ImGuiContext (Dear ImGui 1.84): 2 bools, padding, then ImGuiIO's 24 bytes


def _symbol_value(path: str, name: bytes):
    """The value of the symbol ``name`` in the ELF64 little-endian file ``path`` (its .symtab), or None."""
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
        if data[:6] != b"\x7fELF\x02\x01":
            return None
        shoff, = struct.unpack_from("<Q", data, 0x28)
        shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
        sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
        for sec in sections:
            if sec[1] != 2:  # SHT_SYMTAB
                continue
            strtab = sections[sec[6]]
            at = data[strtab[4]:strtab[4] + strtab[5]].find(b"\0" + name + b"\0")
            if at < 0:
                return None
            syms = np.frombuffer(data, _ELF_SYM, count=sec[5] // _ELF_SYM.itemsize, offset=sec[4])
            hit = np.flatnonzero(syms["name"] == at + 1)
            value = int(syms["value"][hit[0]]) if len(hit) else None
            del syms
            return value
    return None


def _gimgui_address():
    """Where Taichi's library keeps Dear ImGui's current context pointer in this process (None if unknown)."""
    if not _GIMGUI:
        address = None
        try:
            lib = os.path.realpath(_taichi_core.__file__)
            value = _symbol_value(lib, b"GImGui")
            if value is not None:
                with open("/proc/self/maps") as maps:
                    for line in maps:
                        parts = line.split()
                        if len(parts) >= 6 and int(parts[2], 16) == 0 and os.path.realpath(parts[5]) == lib:
                            address = int(parts[0].split("-")[0], 16) + value
                            break
        except (AttributeError, OSError, ValueError, struct.error):
            address = None
        _GIMGUI.append(address)
    return _GIMGUI[0]


def _place_imgui_ini(target) -> bool:
    """Point the current ImGui context's layout file at ``target`` (a Path; None: no layout file). Only where it
    still names ``imgui.ini`` (a check that the context was found). Returns whether it was set."""
    address = _gimgui_address()
    if address is None:
        return False
    context = ctypes.c_void_p.from_address(address).value
    if not context:
        return False
    slot = ctypes.c_void_p.from_address(context + _INI_OFFSET)
    if not slot.value or ctypes.string_at(slot.value, 10) != b"imgui.ini\0":
        return False
    if target is None:
        slot.value = None
    else:
        text = ctypes.create_string_buffer(os.fsencode(target))
        _KEEP.append(text)
        slot.value = ctypes.addressof(text)
    return True


class HiddenWindow:
    """A hidden ``resolution`` GGUI window with its canvas and scene, opened on demand.

    Opening one closes any other :class:`HiddenWindow` first (its owner reopens it when it next draws:
    check :attr:`is_open`). Its Dear ImGui layer keeps no layout file (module docstring); should that setting
    not be found, :meth:`release` removes the ./imgui.ini ImGui wrote if it was not there before.
    """

    def _layout(self):
        return None  # no layout file

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
        target = self._layout()
        if target is not None:
            try:
                target.parent.mkdir(parents=True, exist_ok=True)
            except OSError:
                target = None
        _place_imgui_ini(target)
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

    def _layout(self):
        return layout_file()  # the panel's layout, kept per user

    def _make(self):
        return ggui(ti.ui.Window, self.title, self.resolution, show_window=True, vsync=False)

    @property
    def running(self) -> bool:
        """False once the user closed the window."""
        return self.window is not None and bool(self.window.running)
