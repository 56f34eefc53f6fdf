"""Import a `taichi-rocks export` USD stage into Blender (4.4 or later) ready to play: the scene's frame rate
set from the stage and the exported camera made the scene camera.

Blender's USD importer sets the frame range from the stage's start and end time codes, and reads every time
code as a frame, but it keeps the scene's own frame rate (24 fps for a new scene) and does not make an imported
camera the scene camera; no USD metadata changes either (tried with Blender 4.5: ``framesPerSecond``,
``timeCodesPerSecond`` and a ``UsdRender.Settings`` prim with a ``camera`` relationship named by the stage's
``renderSettingsPrimPath``). This script does both after the import:

    blender --python tools/blender_import.py -- FILE.usdc [--empty] [--save FILE.blend]
    python tools/blender_import.py FILE.usdc [--empty] [--save FILE.blend]      # with the bpy module

``--empty`` imports into an empty scene instead of the open one (Blender's start-up file has a cube, a light
and a camera); ``--save`` writes the result as a .blend file (with the bpy module nothing is kept otherwise).
The frame rate is the stage's ``framesPerSecond`` (or ``timeCodesPerSecond``): ``render.fps`` = its rounded
value and ``render.fps_base`` = that / the rate, so that 29.97 fps plays as 29.97.
"""

from __future__ import annotations

import argparse
import os
import sys

import bpy


def _pxr_usd():
    """Blender's own USD Python module: on the path inside Blender; beside the bpy module's Python otherwise."""
    try:
        from pxr import Usd
    except ImportError:
        v = sys.version_info
        sys.path.append(os.path.join(bpy.utils.resource_path("LOCAL"), "python", "lib",
                                     f"python{v.major}.{v.minor}", "site-packages"))
        from pxr import Usd
    return Usd


def stage_rate(path: str) -> float:
    """Frames per second of the stage at ``path`` (framesPerSecond, else timeCodesPerSecond)."""
    stage = _pxr_usd().Stage.Open(path)
    layer = stage.GetRootLayer()
    return float(stage.GetFramesPerSecond() if layer.HasFramesPerSecond() else stage.GetTimeCodesPerSecond())


def import_stage(path: str, empty: bool = False) -> dict:
    """Import the stage into the current scene (``empty``: a new empty one), set the frame rate, make the
    imported camera the scene camera; returns what was set."""
    if empty:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    before = set(bpy.data.objects)
    result = bpy.ops.wm.usd_import(filepath=path)
    if "FINISHED" not in result:
        raise RuntimeError(f"{path}: Blender's USD import did not finish ({result})")
    scene = bpy.context.scene
    rate = stage_rate(path)
    scene.render.fps = max(1, round(rate))
    scene.render.fps_base = scene.render.fps / rate
    cameras = [o for o in bpy.data.objects if o not in before and o.type == "CAMERA"]
    if cameras:
        scene.camera = cameras[0]
    return {"fps": rate, "frames": (scene.frame_start, scene.frame_end),
            "camera": scene.camera.name if scene.camera else None}


def _args(argv: list) -> argparse.Namespace:
    if "--" in argv:  # inside Blender: its own arguments come first
        argv = argv[argv.index("--") + 1:]
    elif bpy.app.background and argv and argv[0].endswith(".py"):
        argv = argv[1:]  # python tools/blender_import.py FILE (the bpy module)
    p = argparse.ArgumentParser(prog="blender_import.py", description=__doc__.split("\n")[0])
    p.add_argument("usd", metavar="FILE.usdc")
    p.add_argument("--empty", action="store_true", help="import into an empty scene")
    p.add_argument("--save", metavar="FILE.blend", help="save the scene as a .blend file")
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = _args(sys.argv if argv is None else argv)
    if not os.path.isfile(args.usd):
        print(f"blender_import.py: {args.usd}: no such file", file=sys.stderr)
        return 2
    info = import_stage(os.path.abspath(args.usd), args.empty)
    print(f"blender_import.py: {args.usd}: frames {info['frames'][0]}-{info['frames'][1]} at {info['fps']:g} fps, "
          f"camera {info['camera']}")
    if args.save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save))
    return 0


if __name__ == "__main__":
    status = main()
    if status and not bpy.app.background:
        print("blender_import.py: nothing imported", file=sys.stderr)
    elif status:
        sys.exit(status)
