"""The game: a Panda3D ShowBase with the rock system inside. Each frame (at time t, dt after the last):

    game    the player's command: the keyboard through the car model, or a recorded drive (controls.py)
    rocks   sim.drive("player", pose); sim.advance_to(t); events = sim.impacts(); rows = sim.changes()
    mirror  the rows into the mirror and the rocks' vertex buffer (rocks.py)
    game    the vehicles at their poses, the hits' flashes and marks (hits.py), the camera, the HUD
    draw    Panda3D's frame

Offscreen, t = f / 60 for frame f (a 60 Hz clock, whatever the frame costs), and each frame may be written as a
PNG; in a window, t follows the wall clock (at most 0.1 s a frame). The world is drawn in metres, z up, as the
simulation's (Panda3D's default frame): a point is drawn at its world position minus ``origin`` (float32).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from panda3d.core import (Filename, Geom, GeomNode, GeomPoints, GeomVertexData,
                          GeomVertexFormat, GraphicsPipeSelection, OmniBoundingVolume, PNMImage, TextNode,
                          loadPrcFileData)

from taichi_rocks import Simulation
from taichi_rocks.config.drivefile import drive_text
from taichi_rocks.motion.cabin import cabin_of

from . import meshes
from .budget import Budget
from .car import Car
from .controls import Keyboard, Replay
from .hits import Glass, HitView
from .rocks import RockMesh
from .scene import PLAYER, TRUCK, game_scene, road_centre
from .vehicles import VehicleModel

FPS = 60.0  # the offscreen clock
SKY = (0.60, 0.73, 0.88, 1.0)
ROAD_HALF = 3.6  # m
GROUND_CELL = 40.0  # m: the ground's triangles (the software renderer loses parts of huge ones cut by the near plane)
CHASE = dict(back=7.4, up=4.3, ahead=10.0, aim_z=0.2, fov=66.0, lag=0.25)  # m, deg, s
COCKPIT_FOV = 78.0


@dataclass
class Options:
    offscreen: bool = True
    frames: int = 300
    out: Path | None = None
    size: tuple = (960, 540)
    camera: str = "chase"
    drive: Path | None = None  # a recorded drive replayed (offscreen: the default follow.drive)
    rocks: int | None = None
    truck_tires: bool = True
    bare: bool = False
    record_drive: Path | None = None
    software: bool = True  # Panda3D's software renderer (offscreen always)


def configure_panda(opts: Options) -> None:
    """Panda3D's settings, before ShowBase starts: offscreen with the software renderer, or a window."""
    w, h = opts.size
    lines = [f"win-size {w} {h}", "sync-video 0", "audio-library-name null", "window-title taichi_rocks: gravel",
             "print-pipe-types 0",
             "notify-level-x11display fatal", "notify-level-device fatal", "notify-level-display fatal",
             "framebuffer-multisample 0"]
    if opts.offscreen:
        lines += ["window-type offscreen", "load-display p3tinydisplay"]
    elif opts.software:
        lines += ["load-display p3tinydisplay"]
    loadPrcFileData("rockgame", "\n".join(lines))


def offscreen_pipe():
    """The software renderer's pipe that needs no X server (TinyOffscreenGraphicsPipe), or None: offscreen, Panda3D
    would otherwise take the X11 pipe wherever an X server answers, and depend on it."""
    sel = GraphicsPipeSelection.getGlobalPtr()
    for i in range(sel.getNumPipeTypes()):
        t = sel.getPipeType(i)
        if t.getName() == "TinyOffscreenGraphicsPipe":
            return sel.makePipe(t)
    return None


class Game:
    def __init__(self, opts: Options):
        from direct.showbase.ShowBase import ShowBase

        configure_panda(opts)
        self.opts = opts
        if opts.offscreen:
            self.base = ShowBase(windowType="none")
            self.base.pipe = offscreen_pipe() or self.base.pipe
            self.base.openDefaultWindow(type="offscreen")
        else:
            self.base = ShowBase()
        self.base.disableMouse()
        self.base.win.setClearColor(SKY)
        self.scene = game_scene(opts.rocks, opts.truck_tires)
        self.sim = Simulation(self.scene)
        self.player = self.scene.vehicle_index(PLAYER)
        self.truck = self.scene.vehicle_index(TRUCK)
        spec = self.scene.vehicles[self.player]
        self.origin = np.zeros(3)  # the render frame's origin, world m (the loop lies within 300 m of it)
        self.world = self.base.render.attachNewNode("world")
        self._ground()
        radii = self.sim.state().radii  # once: a rock's radius never changes, and changes() does not carry it
        self.rocks = RockMesh(radii, self.origin, self.world)
        self._vehicles()
        ground_local = float(self.scene.world.ground_z) - float(self.sim.origin[2])
        self.hits = HitView(self.models, {self.player: Glass(cabin_of(spec))}, self.scene.impacts.thresholds(),
                            self.scene.impacts.damage_by, ground_local)
        start = self.sim.vehicle_poses()[self.player]
        self._player_at = np.array(start.position, np.float64)  # where the player was at the last frame
        self.car = Car(float(start.position[0]), float(start.position[1]), float(start.heading), float(start.speed),
                       wheelbase=float(spec.wheelbase))
        drive = opts.drive
        self.controls = Replay(drive, spec.wheelbase) if drive else Keyboard(
            self.base.mouseWatcherNode, self.car, float(spec.tire_radius))
        self.budget = Budget()
        self.log = {"t": [], "hits": [], "rows": [], "flying": [], "view": [], "eye": []}
        self.t, self.frame_no, self.quit = 0.0, 0, False
        self.cam_heading = float(start.heading)
        self._hud()
        self.set_camera(opts.camera)
        self.bare = self._bare_points() if opts.bare else None
        if not opts.offscreen:
            self.base.accept("escape", self._stop)
            self.base.accept("c", lambda: self.set_camera("cockpit" if self.camera == "chase" else "chase"))
            self.base.accept("r", self.respawn)

    # ------------------------------------------------------------------------------------------ the scene
    def _ground(self) -> None:
        centre = road_centre(self.scene)
        lo, hi = centre.min(axis=0) - 700.0, centre.max(axis=0) + 700.0  # out under the hills (_horizon)
        verts, tris = meshes.grid(lo, hi, GROUND_CELL)
        verts -= self.origin
        tile = 3.0  # m of ground a texture repeat
        uv = (verts[:, :2] - verts[0, :2]) / tile
        ground = self.world.attachNewNode(meshes.textured("ground", verts, uv, tris))
        ground.setTexture(meshes.texture("gravel", meshes.gravel_texture()))
        v, uv, tris = meshes.ribbon(centre - self.origin[:2], ROAD_HALF, 0.0, 8.0)
        road = self.world.attachNewNode(meshes.textured("road", v, uv, tris))
        road.setTexture(meshes.texture("road", meshes.road_texture()))
        for k, node in enumerate((ground, road)):  # flat on the ground: drawn first, under everything
            node.setBin("background", k)
            node.setDepthWrite(False)
            node.setDepthTest(False)
            node.setLightOff()
        self._horizon(centre)

    def _horizon(self, centre) -> None:
        """A ring of low hills far out, so the ground meets the sky at a soft edge."""
        mid, r, n = centre.mean(axis=0) - self.origin[:2], 650.0, 72
        a = np.linspace(0, 2 * np.pi, n, endpoint=False)
        rng = np.random.default_rng(3)
        top = 18.0 + 22.0 * np.abs(np.sin(3 * a + 1.0)) * rng.uniform(0.6, 1.0, n)
        ring = np.stack([mid[0] + r * np.cos(a), mid[1] + r * np.sin(a)], 1)
        verts = np.concatenate([np.column_stack([ring, np.zeros(n)]), np.column_stack([ring, top])])
        cols = np.concatenate([np.tile(meshes.rgba((0.48, 0.47, 0.42)), (n, 1)),
                               np.tile(meshes.rgba((0.55, 0.62, 0.66)), (n, 1))])
        k = np.arange(n)
        j = (k + 1) % n
        tris = np.concatenate([np.stack([k, n + k, j], 1), np.stack([j, n + k, n + j], 1)])
        hills = self.world.attachNewNode(meshes.triangles("hills", verts, cols, tris))
        hills.setTwoSided(True)
        hills.setBin("background", 2)
        hills.setDepthWrite(False)
        hills.setLightOff()

    def _vehicles(self) -> None:
        lit = self.world.attachNewNode("vehicles")  # lit on the host (vehicles.py Lit)
        ground_z = float(self.scene.world.ground_z)
        self.models = [VehicleModel(v, lit, ground_z, interior=(i == self.player))
                       for i, v in enumerate(self.scene.vehicles)]

    def _hud(self) -> None:
        from direct.gui.OnscreenText import OnscreenText

        self.hud = OnscreenText(text="", pos=(-1.72, 0.9), scale=0.05, fg=(1, 1, 1, 1), shadow=(0, 0, 0, 0.8),
                                align=TextNode.ALeft, mayChange=True)
        self.hud.setX(-self.base.getAspectRatio() + 0.05)
        if not self.opts.offscreen and not self.opts.drive:
            self.help = OnscreenText(text="W/S throttle, brake   A/D steer   Space burnout   C camera   R respawn   "
                                          "Esc quit", pos=(0, -0.93), scale=0.045, fg=(1, 1, 1, 1),
                                     shadow=(0, 0, 0, 0.8), mayChange=False)

    def set_camera(self, name: str) -> None:
        self.camera = name
        lens = self.base.camLens
        lens.setNearFar(0.05 if name == "cockpit" else 0.3, 1000.0)  # a 16-bit depth buffer: near as far as it may
        player = self.models[self.player]
        player.show_interior(name == "cockpit")
        cam = self.base.camera
        if name == "cockpit":
            lens.setFov(COCKPIT_FOV)
            cab = player.cabin
            eye = np.array(cab.eye)
            cam.reparentTo(player.node)
            cam.setPos(*eye)
            cam.lookAt(player.node, *(eye + (10.0, 0.0, -0.9)))
        else:
            lens.setFov(CHASE["fov"])
            cam.reparentTo(self.base.render)
        w, h = self.opts.size
        self.pixel_angle = 2.0 * math.tan(math.radians(lens.getFov()[1]) / 2.0) / h

    def _chase(self, pose, dt: float) -> None:
        a = 1.0 - math.exp(-dt / CHASE["lag"])
        self.cam_heading += a * math.remainder(pose.heading - self.cam_heading, 2.0 * math.pi)
        f = np.array([math.cos(self.cam_heading), math.sin(self.cam_heading), 0.0])
        p = np.asarray(pose.position, np.float64) - self.origin
        eye = p - CHASE["back"] * f + (0.0, 0.0, CHASE["up"])
        aim = p + CHASE["ahead"] * f + (0.0, 0.0, CHASE["aim_z"])
        self.base.camera.setPos(*eye)
        self.base.camera.lookAt(*aim)

    def respawn(self) -> None:
        """The car back on the road, 9 m behind the truck, at its speed (a jump: no launches along it)."""
        if isinstance(self.controls, Keyboard):
            tp = self.sim.vehicle_poses()[self.truck]
            f = np.array([math.cos(tp.heading), math.sin(tp.heading)])
            x, y = np.asarray(tp.position[:2]) - 9.0 * f
            self.car.place(float(x), float(y), float(tp.heading), float(tp.speed))
            self.hits.clear(self.player)

    def _stop(self) -> None:
        self.quit = True

    # ------------------------------------------------------------------------------------------ a frame
    def frame(self, t: float) -> None:
        """One frame at time ``t`` (module docstring), timed by part."""
        dt = t - self.t
        sim, b = self.sim, self.budget
        t0 = time.perf_counter()
        cmd = self.controls.command(t, dt)
        t1 = time.perf_counter()
        sim.drive(PLAYER, cmd.position, cmd.heading, speed=cmd.speed, yaw_rate=cmd.yaw_rate,
                  wheel_spin=cmd.wheel_spin)
        sim.advance_to(t)
        events = sim.impacts()
        rows = sim.changes()
        t2 = time.perf_counter()
        pose = sim.vehicle_poses()[self.player]
        self.rocks.apply(rows, pose.position - self._player_at)
        self._player_at = np.array(pose.position, np.float64)
        t3 = time.perf_counter()
        self._show(t, dt, cmd, events)
        t4 = time.perf_counter()
        b.add("rocks", 1e3 * (t2 - t1))
        b.add("mirror", 1e3 * (t3 - t2))
        b.add("game", 1e3 * ((t1 - t0) + (t4 - t3)))
        self.t = t
        self.frame_no += 1
        self._log(t, events, rows)

    def _show(self, t: float, dt: float, cmd, events) -> None:
        poses = self.sim.vehicle_poses()
        for i, (model, pose) in enumerate(zip(self.models, poses)):
            steer = cmd.steer if i == self.player else 0.0
            model.place(pose.position, pose.heading, self.origin, pose.speed, dt, steer)
        if self.camera == "chase":
            self._chase(poses[self.player], dt)
        self.hits.add(events, t)
        self.hits.update(t, self.base.camera, self.pixel_angle)
        if self.frame_no % 6 == 0:
            self._hud_text(poses)

    def _hud_text(self, poses) -> None:
        p, tr = poses[self.player], poses[self.truck]
        gap = float(np.hypot(*(tr.position - p.position)[:2])) - 0.5 * (
            self.scene.vehicles[self.truck].length + self.scene.vehicles[self.player].length)
        n = self.hits.counts[self.player]
        self.hud.setText(f"{3.6 * p.speed:5.0f} km/h   gap {gap:5.1f} m   hits {int(n.sum())}   "
                         f"chips {int(n[1])}   cracks {int(n[2])}   stones in the air {self.flying}")

    @property
    def flying(self) -> int:
        return int(np.count_nonzero(self.rocks.phase == 1))

    def _log(self, t: float, events, rows) -> None:
        self.log["t"].append(t)
        self.log["hits"].append(len(events))
        self.log["rows"].append(len(rows.ids))
        self.log["flying"].append(self.flying)
        self.log["view"].append(self.view_matrix())
        self.log["eye"].append(np.array(self.base.cam.getPos(self.base.render), np.float64) + self.origin)

    def view_matrix(self) -> np.ndarray:
        """(4, 4): render-frame point (row vector [x y z 1]) to clip space of the camera now; pixel = ((ndc_x + 1)
        W / 2, (1 - ndc_y) H / 2), ndc = clip[:3] / clip[3]."""
        cam_to_world = np.array(self.base.cam.getMat(self.base.render), np.float64).reshape(4, 4)
        proj = np.array(self.base.camLens.getProjectionMat(), np.float64).reshape(4, 4)
        return np.linalg.inv(cam_to_world) @ proj

    def draw(self) -> None:
        t0 = time.perf_counter()
        self.base.taskMgr.step()
        self.budget.add("draw", 1e3 * (time.perf_counter() - t0))

    # ------------------------------------------------------------------------------------------ the bare frame
    def _bare_points(self) -> tuple:
        n = self.rocks.n
        vdata = GeomVertexData("bare", GeomVertexFormat.getV3c4(), Geom.UHDynamic)
        vdata.setNumRows(n)
        prim = GeomPoints(Geom.UHStatic)
        prim.addConsecutiveVertices(0, n)
        geom = Geom(vdata)
        geom.addPrimitive(prim)
        node = GeomNode("bare")
        node.addGeom(geom)
        node.setBounds(OmniBoundingVolume())  # its vertices change behind the engine's back: never culled
        node.setFinal(True)
        np_ = self.base.render.attachNewNode(node)
        np_.hide()
        return np_, vdata

    def _draw_bare(self) -> None:
        """The engine alone: the scene hidden, the mirror's points re-uploaded whole, drawn from the same camera."""
        node, vdata = self.bare
        self.world.hide()
        self.base.aspect2d.hide()
        node.show()
        t0 = time.perf_counter()
        v = meshes.vertex_view(vdata)
        v["p"] = self.rocks.positions - self.origin
        v["c"] = (140, 130, 120, 255)
        self.base.graphicsEngine.renderFrame()
        self.budget.add("bare", 1e3 * (time.perf_counter() - t0))
        node.hide()
        self.world.show()
        self.base.aspect2d.show()

    # ------------------------------------------------------------------------------------------ running
    def save_png(self, path: Path) -> None:
        t0 = time.perf_counter()
        tmp = path.with_name(path.stem + ".part.png")
        img = PNMImage()
        # RGB only: the software renderer leaves alpha 0 where it drew points, which a viewer shows as holes
        if not self.base.win.getScreenshot(img):
            raise OSError(f"{path}: could not read the frame back")
        img.removeAlpha()
        if not img.write(Filename.fromOsSpecific(str(tmp))):
            raise OSError(f"{path}: could not write the frame")
        os.replace(tmp, path)
        self.budget.add("png", 1e3 * (time.perf_counter() - t0))

    def run_offscreen(self) -> None:
        for f in range(1, self.opts.frames + 1):
            self.frame(f / FPS)
            self.draw()
            if self.opts.out is not None:
                self.save_png(self.opts.out / f"frame_{f:04d}.png")
            if self.bare is not None:
                self._draw_bare()

    def run_window(self) -> None:
        clock = time.perf_counter()
        while not self.quit and (self.opts.frames <= 0 or self.frame_no < self.opts.frames):
            now = time.perf_counter()
            self.frame(self.t + min(now - clock, 0.1) if self.frame_no else self.t + 1.0 / FPS)
            clock = now
            self.draw()
            if self.bare is not None:
                self._draw_bare()
            if self.base.win.isClosed():
                break

    def write_log(self, path: Path) -> None:
        """What each frame showed, for a reader of the PNGs: its time, the hits it took, the rows it wrote, the
        stones in the air, the camera's view matrix (:meth:`view_matrix`) and its eye (world m); the render origin
        and the frame size."""
        tmp = path.with_name(path.stem + ".part.npz")
        np.savez(tmp, t=np.array(self.log["t"]), hits=np.array(self.log["hits"]), rows=np.array(self.log["rows"]),
                 flying=np.array(self.log["flying"]), view=np.array(self.log["view"]).reshape(-1, 4, 4),
                 eye=np.array(self.log["eye"]).reshape(-1, 3),
                 origin=self.origin, size=np.array(self.opts.size))
        os.replace(tmp, path)

    def hits_total(self) -> int:
        return int(self.hits.taken)

    def drive_text(self) -> str:
        return drive_text(self.sim.drive_track(PLAYER), ["the player of examples/rockgame/road.toml, driven in "
                                                         "examples/panda3d_game.py"])

    def close(self) -> None:
        self.base.destroy()

