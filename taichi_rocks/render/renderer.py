"""Rendering of a :class:`~taichi_rocks.engine.simulation.Simulation` with Taichi GGUI, offscreen or in a window.

Every frame is declared from scratch (GGUI is immediate mode), drawn into a hidden window
(:mod:`.window`) and read back (``render``), or declared in a window on the screen (``view``,
app/view.py: the same code draws both). A frame is made of two layers:

1. the background, filled by Taichi kernels: the *resting* rocks splatted in software by the rock pass
   (:mod:`.splat`, run by :mod:`.culling`) into the buffers of :mod:`.kernels`, then sky and ground
   (:mod:`.ground`, given the sun and the shadows by :mod:`.sunlight`);
2. the GGUI 3D scene: vehicles (a car, van or truck body of a few boxes, lights, four wheels that turn at
   their angular velocity; all in one mesh instance, :mod:`.bodies`, :mod:`.meshes`; from the driver's view,
   the ridden vehicle's greenhouse left out and its windscreen's frame drawn, :mod:`.interior`; all in
   :mod:`.vehicles`), the *flying* rocks as
   ``scene.particles`` from compact f32 fields (atomic-counter compaction in the same pass, ``index_count``
   = the count, power-of-two buckets) and tumbling meshes (:mod:`.tumbling`), the impacts' flashes and marks
   (:mod:`.hits`: each mark made once, posed each frame), debug overlays (:mod:`.overlays`) as ``scene.lines``.

Offscreen, GGUI draws first and the ground pass then paints sky and ground straight into the frame, wherever
GGUI left its clear colour, and copies GGUI's pixels elsewhere (no ground computed under a vehicle, no background
image made and read again); in a shown window the ground pass paints the background image, the canvas's
``set_image`` under the 3D scene, which GGUI draws over it (the same pixels). Where a frame's time goes, stage by
stage: :mod:`.stages` (``render --profile``).

Why: lavapipe shades GGUI particles at ~2 us per particle plus ~0.2 us per covered pixel, so the ~40-60k
visible rocks of a 200k-rock bed cost 150-200 ms a frame at 720p as particles, and a full-screen ground mesh
~45 ms; the two-layer frame costs ~100 ms in total. ``rocks="particles"`` keeps every rock a GGUI particle
(far resting rocks thinned by a hash of rock_id to ``lod_pixels``), for comparison.

GGUI 1.7.4 quirks handled here (see also :mod:`.window`):

* particles come out ``width / height`` times too large (Particles_vk.vert scales the sprite by the vertical
  fov, then its y again by the aspect ratio): radii are multiplied by height / width;
* ``mesh_instance`` lights the *untransformed* mesh (Mesh_vk.vert forwards the model-space position and
  normal to the lighting), so a yawed vehicle would keep the shading of an unrotated one: vehicles are one
  mesh whose vertices and normals are transformed on the host each frame;
* the image comes back (W, H, 4) float and y-flipped (``get_image_buffer_as_numpy``: GGUI has no 8-bit or
  partial read-back; the ground pass turns it upright, render/ground.py); capture exactly once per frame; a 3D
  scene leaks ~0.3 MB per captured frame on lavapipe: the window is recreated every ``window_every`` frames
  (the camera state lives in :class:`.camera.CameraRig` and carries over);
* a plain ``scene.mesh`` now and then vanishes from a frame, and often again when drawn again: Mesh_vk.vert
  takes model = I * (1 - a) + M * a with a = 0 and M read from a buffer GGUI never fills without transforms, and
  NaN or Inf left in that memory survives the ``* 0``. So the vehicles' mesh is a ``mesh_instance`` with one
  explicit identity matrix (render/vehicles.py ``VehicleLayer.identity``); the lost-renderable guard (a frame
  whose vehicles are missing is drawn again) stays as a safety net.

Its parts, one job each: the options and the camera (:mod:`.settings`: ``Settings``, ``Views``), the fields and
their pool (:mod:`.buffers`), the rocks (:mod:`.culling`), the sun and the shadows (:mod:`.sunlight`), the
vehicles and their marks (:mod:`.vehicles`); the :class:`Renderer` here is the frame that calls them.
"""

from types import SimpleNamespace

import numpy as np
import taichi as ti

from ..engine import drawing
from . import kernels as K
from .buffers import POOL, lease_frame
from .camera import GL_UP, NEAR, View
from .culling import RockLayer
from .dust import draw_dust, soft_dust
from .looks import AMBIENT, KEY, SUN_COLOR
from .markmesh import Sight
from .settings import (DEFAULT_LOD_PIXELS, ROCK_MODES, SHOTS, WINDOW_EVERY, Settings, Views, camera_basis,
                       check_rocks)
from .splat import ALL, COMPACT, SPLAT
from .stages import Stages
from .sunlight import paint_sky_and_ground
from .vehicles import VehicleLayer
from .window import HiddenWindow, ggui

__all__ = ["Renderer", "DEFAULT_LOD_PIXELS", "ROCK_MODES", "WINDOW_EVERY", "SHOTS", "check_rocks"]

GLITCH_DROP = 0.3  # a frame whose GGUI pixels fall below this fraction of the last frame's is drawn again
GLITCH_RETRIES = 3  # at most this many extra draws of one frame


class Renderer:
    """Draws ``sim`` into a hidden GGUI window; :meth:`render_frame` returns the image (H, W, 3) uint8.

    ``resolution`` (even sides), ``fps`` and ``shadows`` default to the scene's [render] table. ``rocks``: "splat"
    (resting rocks splatted into the background image by a Taichi kernel, flying rocks GGUI particles; the default)
    or "particles" (every visible rock a GGUI particle). ``lod_pixels`` ("particles" only): resting rocks whose
    projected radius is below this many pixels are thinned (a fraction q^2 kept, chosen by a hash of rock_id, drawn
    1/q larger, q = projected radius / lod_pixels); 0 disables it. ``window_every``: frames between window
    re-creations (0: never). ``stages`` (render/stages.py) accumulates the frames' seconds per stage (the
    camera, the rock pass, the marks, GGUI's declaration, its drawing and read-back, sky and ground, the dust,
    the window). ``last_count``: rocks GGUI drew in the last frame. ``target``: the window to draw into (default:
    a :class:`.window.HiddenWindow`, read back); a :class:`.window.ShownWindow` gets the frame declared and
    nothing read back (:meth:`render_frame` returns None; never recreated). ``flags`` (bed_edge, tire_rays,
    hash_cells, tread_patch) may change between frames.

    Args:
        sim: the Simulation to draw (its scene gives the camera, the light and the defaults below).
        resolution: (width, height), even; default ``[render] resolution``.
        fps: frames per second of the frames drawn (the camera's smoothing and shots follow it); default
            ``[render] fps``.
        rocks: "splat" or "particles".
        lod_pixels: "particles" only: the projected radius below which resting rocks are thinned (0: never).
        window_every: frames between re-creations of the hidden window (0: never).
        shadows: draw shadows; default ``[render] shadows``.
        target: the window to draw into (default: a hidden one, read back).

    ``render_frame(view=None)`` returns the frame as a (H, W, 3) uint8 array (None for a shown window);
    ``close()`` gives the renderer's buffers back to its pool (the next renderer of the same sizes starts
    with its kernels compiled).

    Its parts: ``settings`` (:class:`.settings.Settings`), ``views`` (:class:`.settings.Views`: the camera, its
    lens, the sun), ``fields`` (render/buffers.py FrameFields, leased from the pool), ``rock_layer``
    (:class:`.culling.RockLayer`), ``vehicles`` (:class:`.vehicles.VehicleLayer`) and ``hits`` (its flashes and
    marks).
    """

    def __init__(self, sim, resolution=None, fps=None, *, rocks: str = "splat",
                 lod_pixels: float = DEFAULT_LOD_PIXELS, window_every: int = WINDOW_EVERY, shadows=None,
                 target=None):
        self.sim = sim
        self.settings = s = Settings.of(sim.scene, resolution, fps, rocks, lod_pixels, window_every, shadows)
        if target is not None and tuple(target.resolution) != tuple(s.resolution):
            raise ValueError(f"the window is {target.resolution}, the renderer {s.resolution}")
        self.views = Views(sim.scene, s.resolution)
        self.frames_drawn = 0
        self.stages = Stages()  # where the frames' time went (render/stages.py)
        self._ggui_camera = ggui(ti.ui.Camera)  # GGUI's camera of the 3D layer, set from the view each frame
        self._ggui_camera.up(*GL_UP)
        self._ggui_camera.fov(self.views.fov)
        self._ggui_camera.z_near(NEAR)
        self._ggui_camera.z_far(max(1000.0, 3.0 * s.draw_distance))
        # the buffers are leased from the pool: given back by close() or when this renderer is garbage-collected
        # (engine/trees.py)
        w, h = s.resolution
        self.fields = lease_frame(self, w, h, s.rocks == "splat", s.shadows, drawing.slot_total(sim.world))
        # rocks: compact buckets (power-of-two capacities), allocated when first needed; flying ones of a few
        # pixels and more as oriented rock meshes (:mod:`.tumbling`) if the simulation tumbles them
        self.rock_layer = RockLayer(self.fields, sim.n_rocks, drawing.has_orientations(sim.world))
        self._out = np.empty((h, w, 3), np.uint8)
        self._prev_drawn = 0
        self.redraws = 0  # extra draws of the 3D layer (see render_frame)
        self.vehicles = VehicleLayer(sim.scene)
        self.vehicles.build(sim.scene, sim.fleet.paths, self.views.inside_needed())
        self.hits = self.vehicles.hits  # the impacts' flashes and windscreen marks (render/hits.py)
        self.inside = None  # the vehicle whose cabin the camera looks out of this frame
        self._overlays = self.fields.overlays
        self._dust = None  # the dust's puffs over an offscreen frame (render/dust.py), made on the first with dust
        self._dust_gl = None  # the dust's GGUI particles in a shown window
        self._overlays.flags = s.flags
        self._raw = None
        self._win = HiddenWindow(s.resolution) if target is None else target
        if self._win.shown:
            s.window_every = 0  # recreating a shown window would flash
        self._win.open()  # now, so that a machine without Vulkan fails before any frame is simulated

    # ------------------------------------------------------------------------------------ settings and views
    resolution = property(lambda self: self.settings.resolution)
    fps = property(lambda self: self.settings.fps)
    flags = property(lambda self: self.settings.flags)
    rig = property(lambda self: self.views.rig, doc="the camera (motion/camera.py SceneCamera)")
    view_name = property(lambda self: self.views.view_name)
    tan_x = property(lambda self: self.views.tan_x)
    tan_y = property(lambda self: self.views.tan_y)
    px_per_rad = property(lambda self: self.views.px_per_rad)
    last_count = property(lambda self: self.rock_layer.last_count)
    tiles_in_view = property(lambda self: self.rock_layer.tiles_in_view,
                             doc="tiles of the store the last rock pass visited (active stepping)")

    def set_view(self, name: str) -> None:
        """Frame the scene with another view preset (chase, side, low, orbit, driver, bonnet:
        :func:`.camera.scene_camera`; the scene's own view keeps its offset and aim), or with the scene's own
        camera and its shots (``SHOTS``). The new camera snaps to its place at the next frame."""
        self.views.set_view(self.sim.scene, name)
        if not self.vehicles.covers(self.views.inside_needed()):
            self.vehicles.build(self.sim.scene, self.sim.fleet.paths, self.views.inside_needed())

    @property
    def follow(self) -> int:
        """The vehicle the camera rides with in the shot of its last update."""
        return self.rig.shot.rides

    @property
    def target(self) -> int:
        """The vehicle the camera looks at in the shot of its last update."""
        return self.rig.shot.target

    def view(self) -> View:
        """Advance the camera to ``sim.time``; return the view in local f32 coordinates:
        (eye, target, forward, right, up, heading). Calling it twice at the same time changes nothing."""
        return self.views.view(self.sim)

    def sun_direction(self, heading: float) -> np.ndarray:
        """Unit vector towards the sun (:func:`.camera.sun_direction`; ``heading``: the rig's)."""
        return self.views.sun_direction(heading)

    # ------------------------------------------------------------------------------------------------- frame
    def cull(self, eye, fwd, right, up, sun, part: int = ALL) -> int:
        """Cull the rocks; splat the resting ones ("splat" mode) and compact those GGUI draws into a bucket.
        Return how many GGUI draws (render/culling.py; ``last_count``: as particles, ``tiles_in_view``: the
        tiles of the store the pass visited). ``part``: all of it, or the compaction or the splats alone
        (render/splat.py)."""
        return self.rock_layer.cull(self.sim, self.settings, self.views, eye, fwd, right, up, sun, part)

    def render_frame(self, view: View = None):
        """Draw the simulation's current state; return the upright image, (H, W, 3) uint8 (None in a shown
        window: the frame is declared there, for its owner to show). ``view``: look from there instead of the
        rig's view (the rig still advances: its heading turns the sun, see :meth:`sun_direction`).

        The returned array is reused by the next call: copy it to keep it.
        """
        st = self.stages
        st.start()
        sim = self.sim
        eye, target, fwd, right, up, heading = self.view()
        self.inside = self.views.inside_now() if view is None else None
        if view is not None:
            eye, target, fwd, right, up = view[:5]
        # offscreen, the rock pass splats after GGUI drew, not under what it drew (render/splat.py); with dust,
        # all before (the dust is depth-tested against the rocks' splats, pixels GGUI drew included)
        split = not self._win.shown and self.settings.rocks == "splat" and drawing.has_tiles(sim.world) and \
            "dust" not in sim.plan.effects
        f = SimpleNamespace(eye=eye, target=target, fwd=fwd, right=right, up=up, sun=self.sun_direction(heading),
                            origin=np.asarray(sim.origin, np.float64), split=split)
        st.lap("camera")
        self.cull(eye, fwd, right, up, f.sun, COMPACT if split else ALL)
        f.poses = sim.vehicle_poses()
        st.lap("culling")
        if not self._win.shown:  # the dust's puffs, summed while the rocks' depths are there (render/dust.py)
            self._dust = soft_dust(self._dust, sim, self.settings)
            if self._dust is not None:
                self._dust.splat(self.fields.buf, sim, self.settings, self.views, (eye, target, fwd, right, up),
                                 f.poses, f.origin, self.inside)
            st.lap("dust")
        self.hits.update(sim)
        st.lap("marks")
        if self._win.shown:  # the background image under the window's 3D scene; nothing to read back
            self._paint(f)
            self._declare_ggui(f)
            self.frames_drawn += 1
            return None
        drawn = self._draw_ggui(f)
        for _ in range(GLITCH_RETRIES):
            # GGUI 1.7.4 on lavapipe now and then loses a whole renderable (seen: the vehicles' mesh) in one
            # frame: a collapse of the pixels GGUI drew, or a vehicle in view that hardly covers its screen box
            # (VehicleLayer.lost), is that, not the scene: draw the 3D layer again (and the rock pass, whose
            # splats the ground pass took)
            if drawn >= GLITCH_DROP * self._prev_drawn and \
                    not self.vehicles.lost(self._raw, eye, fwd, right, up, self.views, self.settings):
                break
            self.redraws += 1
            self.cull(eye, fwd, right, up, f.sun, COMPACT if split else ALL)
            st.lap("culling")
            drawn = self._draw_ggui(f)
        self._prev_drawn = drawn
        if self._dust is not None:
            self._dust.blend(self._out, self._raw, sim)
            st.lap("dust")
        self.frames_drawn += 1
        every = self.settings.window_every
        if every > 0 and self.frames_drawn % every == 0:
            self._win.close()
            self._win.open()
            st.lap("window")
        return self._out

    def _draw_ggui(self, f) -> int:
        """Declare the 3D layer of frame ``f``, draw it, read it back and paint the background under it into
        ``self._out``; return how many pixels GGUI drew."""
        win = self._declare_ggui(f)
        raw = win.window.get_image_buffer_as_numpy()  # (W, H, 4) float32, y up; consumes the frame
        self.stages.lap("readback")
        if f.split:  # the resting rocks and the shadows, where GGUI drew nothing
            K.cover_from(raw, self.fields.buf)
            self.cull(f.eye, f.fwd, f.right, f.up, f.sun, SPLAT)
            self.stages.lap("culling")
        self._paint(f, (raw, self._out))
        self._raw = raw
        return int(self.fields.buf.drawn_px[None])

    def _paint(self, f, merge=None) -> None:
        """Sky, ground and the splatted rocks of frame ``f`` (render/sunlight.py, render/ground.py): into the
        background image, or (``merge`` = (GGUI's read-back, the frame)) into the frame wherever GGUI drew
        nothing."""
        paint_sky_and_ground(self.fields.buf, camera_basis(f.eye, f.fwd, f.right, f.up),
                             self.views.frustum(self.settings.draw_distance), self.settings, self.views.ground_z,
                             self.sim.scene.vehicles, f.poses, f.origin, f.sun, merge)
        self.stages.lap("sky_ground")

    def _declare_ggui(self, f):
        """Declare frame ``f``'s GGUI layer (a shown window: over the background image); return the window."""
        win = self._win
        if not win.is_open:  # closed (or another renderer took over GGUI): reopen
            win.open()
        win.canvas.set_background_color(tuple(k / 255.0 for k in KEY))  # where the ground pass paints (_paint)
        if win.shown:
            win.canvas.set_image(self.fields.buf.sky)
        scene = win.scene
        cam = self._ggui_camera
        cam.position(*(float(x) for x in f.eye))
        cam.lookat(*(float(x) for x in f.target))
        cam.up(*GL_UP)
        scene.set_camera(cam)
        scene.ambient_light(AMBIENT)
        scene.point_light(tuple(float(x) for x in f.eye + 2000.0 * f.sun), SUN_COLOR)
        self.vehicles.declare(scene, f.poses, f.origin, self.sim.time, self.inside, self.settings.wireframe())
        self.rock_layer.declare(scene)
        self.stages.lap("declare")
        w, h = self.settings.resolution
        v = self.views
        self.hits.draw(scene, f.poses, f.origin, Sight(f.eye, f.fwd, f.right, f.up, v.tan_x, v.tan_y, v.px_per_rad,
                                                       self.inside, f.sun, self.settings.wireframe()), h / w)
        self.stages.lap("marks")
        self._overlays.draw(scene, self.sim, f.origin, self.views.ground_z)
        if win.shown:  # offscreen, the dust is composited over the finished frame (render_frame)
            self._dust_gl = draw_dust(self._dust_gl, scene, self.sim, f.origin, self.settings.horizon)
        win.canvas.scene(scene)
        self.stages.lap("declare")
        return win

    def close(self) -> None:
        """Release the window and the imgui.ini GGUI left behind, give the buffers back to the pool (the next
        renderer of their sizes takes them, compiled). It draws no more frames after this; the Simulation stays
        usable. Closing twice does nothing more."""
        self._win.release()
        POOL.give_back(self.fields, self)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
