#!/usr/bin/env bash
# Installs what taichi-rocks needs on a fresh Debian/Ubuntu machine: a Vulkan driver for the offscreen
# renderer (Mesa's software lavapipe when no Vulkan device is present), a virtual X display with xdotool for
# the tests of the window (`taichi-rocks view`), CMake and a C++ compiler for the native host (`make native`)
# and a virtualenv with the package (and Ray, for the sweeps, and Panda3D, for the game of
# examples/panda3d_game.py and its test).
set -euo pipefail
venv=${1:-.venv}

# a Vulkan loader and at least one driver manifest (ICD) in either of the loader's folders; `ls` of both globs
# would fail whenever one folder is empty, and the check then installed Mesa on every machine that had a driver
have_vulkan() {
  { compgen -G '/usr/share/vulkan/icd.d/*.json' || compgen -G '/etc/vulkan/icd.d/*.json'; } >/dev/null &&
    ldconfig -p 2>/dev/null | grep -q 'libvulkan.so.1'
}

# what the machine lacks, installed with one `apt-get update` and one `apt-get install`:
# - a Vulkan driver for the offscreen renderer (Mesa's software lavapipe when no device is present);
# - `taichi-rocks view` opens an on-screen window; its tests run it under a virtual X display (Xvfb) and drive it
#   with xdotool (x11-utils: xdpyinfo, to wait for the display)
packages=()
if ! have_vulkan; then
  echo "setup: no Vulkan driver found; installing Mesa lavapipe (mesa-vulkan-drivers libvulkan1)" >&2
  packages+=(mesa-vulkan-drivers libvulkan1)
fi
if ! command -v Xvfb >/dev/null || ! command -v xdotool >/dev/null || ! command -v xdpyinfo >/dev/null; then
  echo "setup: installing a virtual X display and input tools for the view tests (xvfb xdotool x11-utils)" >&2
  packages+=(xvfb xdotool x11-utils)
fi
# - the native host (native/, docs/native.md) is built with CMake and a C++17 compiler
if ! command -v cmake >/dev/null; then
  echo "setup: installing cmake for the native host (native/)" >&2
  packages+=(cmake)
fi
if ! command -v c++ >/dev/null && ! command -v g++ >/dev/null; then
  echo "setup: installing a C++ compiler for the native host (g++)" >&2
  packages+=(g++)
fi
if [ ${#packages[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null; then SUDO="sudo"; else SUDO=""; fi
  if command -v apt-get >/dev/null; then
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${packages[@]}" >/dev/null
  else
    echo "setup: no apt-get here: install ${packages[*]} (or your system's equivalents) yourself" >&2
  fi
fi

python=${PYTHON:-python3}
if ! "$python" -c 'import sys; sys.exit(not ((3, 11) <= sys.version_info[:2] < (3, 14)))'; then
  echo "setup: taichi-rocks needs Python 3.11-3.13 (Taichi 1.7.4 wheels); found $("$python" --version)" >&2
  exit 2
fi
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install -q --upgrade pip >/dev/null
# the ray extra: the sweep runner's cluster backend, whose tests start a local Ray cluster; the game extra: Panda3D,
# whose software renderer runs the game's test offscreen
"$venv/bin/python" -m pip install -q -e '.[test,usd,ray,game]'
# the package's bytecode, once: an editable install leaves the sources uncompiled, and where Python writes no
# bytecode (PYTHONDONTWRITEBYTECODE) every process would compile them again (the suite starts about a hundred)
"$venv/bin/python" -m compileall -q taichi_rocks >/dev/null
echo "setup: ready ($venv)" >&2
