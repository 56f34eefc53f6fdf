"""Rendering of a :class:`~taichi_rocks.engine.simulation.Simulation` with Taichi GGUI, offscreen or in a window.

Every frame is declared from scratch (GGUI is immediate mode), drawn into a hidden window
(:mod:`.window`) and read back (``render``), or declared in a window on the screen (``view``,
app/view.py: the same code draws both). A frame is made of two layers:

1. the background image, filled by the Taichi kernels of :mod:`.kernels`: sky, ground and the *resting*
   rocks, splatted in software;
2. the GGUI 3D scene: vehicles (a car, van or truck body of a few boxes, lights, four wheels that turn at
   their angular velocity; all in one mesh instance, :mod:`.bodies`, :mod:`.meshes`; from the driver's view,
   the ridden vehicle's greenhouse left out and its windscreen's frame drawn, :mod:`.interior`), the *flying* rocks as
   ``scene.particles`` from compact f32 fields (atomic-counter compaction in the same pass, ``index_count``
   = the count, power-of-two buckets), the impacts' flashes and windscreen marks (:mod:`.hits`), debug
   overlays (:mod:`.overlays`) as ``scene.lines``;

merged by :func:`.kernels.to_u8` wherever GGUI left its clear colour (offscreen); in a shown window the
background image is the canvas's ``set_image`` under the 3D scene, which GGUI draws over it (same pixels).

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
* the image comes back (W, H, 4) float and y-flipped
  (:func:`.kernels.to_u8`); capture exactly once per frame; a 3D scene leaks ~0.3 MB per captured frame on
  lavapipe: the window is recreated every ``window_every`` frames (the camera state lives in
  :class:`.camera.CameraRig` and carries over);
* a plain ``scene.mesh`` now and then vanishes from a frame, and often again when drawn again: Mesh_vk.vert
  takes model = I * (1 - a) + M * a with a = 0 and M read from a buffer GGUI never fills without transforms, and
  NaN or Inf left in that memory survives the ``* 0``. So the vehicles' mesh is a ``mesh_instance`` with one
  explicit identity matrix (``_Vehicles.model``); the lost-renderable guard (a frame whose vehicles are missing is
  drawn again) stays as a safety net.
"""

import math
import time
from types import SimpleNamespace

import numpy as np
import taichi as ti
from taichi.ui.utils import get_field_info

from ..config.resolution import check_resolution
from ..engine import drawing
from ..engine.transfer import put_whole
from ..engine.trees import FieldTrees, Pool
from . import kernels as K
from .dust import draw_dust
from .camera import GL_UP, NEAR, Lens, View, look_at_time, scene_camera, sun_direction
from .looks import AMBIENT, GROUND_A, GROUND_B, HAZE, KEY, SUN_COLOR, horizon_color, rgb
from .bodies import scene_meshes
from .hits import HitLayer
from .interior import interior_of
from .meshes import merge, pose_mesh
from .overlays import Overlays
from .tumbling import MeshBucket, expand, host_buffer, shared_prototypes
from .wheels import Odometer, wheel_angles
from .window import HiddenWindow, ggui

__all__ = ["Renderer", "DEFAULT_LOD_PIXELS", "ROCK_MODES", "WINDOW_EVERY", "SHOTS", "check_rocks"]

DEFAULT_LOD_PIXELS = 0.7  # resting rocks whose projected radius is below this many pixels are thinned
ROCK_MODES = ("splat", "particles")
WINDOW_EVERY = 100  # frames between window re-creations (lavapipe leaks ~0.3 MB per captured frame)
MIN_BUCKET = 4096
MIN_MESHES = 1024  # rocks drawn as meshes per level of detail: the first bucket (the default scene's flying rocks
# in view of a few pixels are ~300-550 at 720p)
MAX_CARS = 32  # vehicles casting a shadow
CONTACT_PX = 3.0  # resting rocks at least this many pixels in radius darken the ground beside them (smaller
# ones are many, and their contact shadows hardly show)
GLITCH_DROP = 0.3  # a frame whose GGUI pixels fall below this fraction of the last frame's is drawn again
GLITCH_RETRIES = 3  # at most this many extra draws of one frame
LOST_COVERAGE = 0.15  # a vehicle in view drawing less than this share of its screen box was lost
SHOTS = "shots"  # the name of the scene's own camera when it has [[camera.shot]] tables (set_view)
INSIDE_VIEWS = ("driver",)  # views from inside the ridden vehicle's cabin (drawn by .interior)


def check_rocks(rocks: str) -> str:
    """The rock drawing mode, or ValueError."""
    if rocks not in ROCK_MODES:
        raise ValueError(f"rocks must be one of {', '.join(ROCK_MODES)}, got {rocks!r}")
    return rocks


def _vec(a):
    return ti.Vector([float(x) for x in a])


class Renderer:
    """Draws ``sim`` into a hidden GGUI window; :meth:`render_frame` returns the image (H, W, 3) uint8.

    ``resolution`` (even sides), ``fps`` and ``shadows`` default to the scene's [render] table. ``rocks``: "splat"
    (resting rocks splatted into the background image by a Taichi kernel, flying rocks GGUI particles; the default)
    or "particles" (every visible rock a GGUI particle). ``lod_pixels`` ("particles" only): resting rocks whose
    projected radius is below this many pixels are thinned (a fraction q^2 kept, chosen by a hash of rock_id, drawn
    1/q larger, q = projected radius / lod_pixels); 0 disables it. ``window_every``: frames between window
    re-creations (0: never). ``timings`` accumulates seconds in ``cull`` (the rock pass: culling, splatting,
    compaction) and ``draw`` (camera, sky and ground, vehicles, overlays, GGUI drawing and the read-back).
    ``last_count``: rocks GGUI drew in the last frame. ``target``: the window to draw into (default: a
    :class:`.window.HiddenWindow`, read back); a :class:`.window.ShownWindow` gets the frame declared and
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
    """

    def __init__(self, sim, resolution=None, fps=None, *, rocks: str = "splat",
                 lod_pixels: float = DEFAULT_LOD_PIXELS, window_every: int = WINDOW_EVERY, shadows=None,
                 target=None):
        self.sim = sim
        self._settings(sim.scene, resolution, fps, rocks, lod_pixels, window_every)
        if target is not None and tuple(target.resolution) != tuple(self.resolution):
            raise ValueError(f"the window is {target.resolution}, the renderer {self.resolution}")
        self.shadows = bool(sim.scene.render.shadows if shadows is None else shadows)
        self._camera_setup(sim.scene)
        self.frames_drawn = 0
        self.last_count = 0
        self.tiles_in_view = 0  # tiles of the store the last rock pass visited (active stepping)
        self.timings = {"cull": 0.0, "draw": 0.0}
        # the vehicles' fields and the other buffers are leased from the pool: given back by close() or when
        # this renderer is garbage-collected (engine/trees.py)
        self._v = None
        self._ggui_camera = ggui(ti.ui.Camera)  # GGUI's camera of the 3D layer, set from the view each frame
        self._ggui_camera.up(*GL_UP)
        self._ggui_camera.fov(self.fov)
        self._ggui_camera.z_near(NEAR)
        self._ggui_camera.z_far(max(1000.0, 3.0 * self.draw_distance))
        # rocks: compact buckets (power-of-two capacities), allocated when first needed; flying ones of a few
        # pixels and more as oriented rock meshes (:mod:`.tumbling`) if the simulation tumbles them
        self.n_rocks = int(sim.n_rocks)
        self._protos = shared_prototypes() if drawing.has_orientations(sim.world) else None
        self._drawn = None
        self.last_meshes = 0
        w, h = self.resolution
        self._f = _lease(self, w, h, rocks == "splat", self.shadows, drawing.slot_total(sim.world))
        self._buf, self._visible = self._f.buf, self._f.visible
        self._out = np.empty((h, w, 3), np.uint8)
        self._prev_drawn = 0
        self.redraws = 0  # extra draws of the 3D layer (see render_frame)
        self._vehicle_fields()
        self._overlays = self._f.overlays
        self._overlays.flags = self.flags
        self.hits = HitLayer(sim.scene)  # the impacts' flashes and windscreen marks (render/hits.py)
        self._raw = None
        self._win = HiddenWindow(self.resolution) if target is None else target
        if self._win.shown:
            self.window_every = 0  # recreating a shown window would flash
        self._win.open()  # now, so that a machine without Vulkan fails before any frame is simulated

    def _settings(self, scene, resolution, fps, rocks, lod_pixels, window_every) -> None:
        """The renderer's options, from the arguments or the scene's [render] table."""
        rs = scene.render
        self.resolution = check_resolution(resolution if resolution is not None else rs.resolution)
        self.fps = float(fps if fps is not None else rs.fps)
        if not self.fps > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        self.background = rgb(rs.background)
        self.horizon = horizon_color(self.background)
        self.draw_distance = float(rs.draw_distance)
        self.tile = float(rs.ground_tile)
        self.rocks = check_rocks(rocks)
        self.lod_pixels = float(lod_pixels)
        self.window_every = int(window_every)
        self.flags = SimpleNamespace(bed_edge=bool(rs.bed_edge), tire_rays=bool(rs.tire_rays),
                                     hash_cells=bool(rs.hash_cells), tread_patch=False)

    def _camera_setup(self, scene) -> None:
        """The scene's camera (its shots: motion/camera.py), its lens; the sun."""
        self.rig = scene_camera(scene)
        self.view_name = SHOTS if scene.camera.shots else scene.camera.view
        self.fov = float(scene.camera.fov)
        self.tan_x, self.tan_y, self.px_per_rad = Lens.of(self.fov, *self.resolution)
        self.ground_z = float(scene.world.ground_z)
        self.sun = (scene.render.sun, scene.render.sun_frame)

    def set_view(self, name: str) -> None:
        """Frame the scene with another view preset (chase, side, low, orbit, driver, bonnet:
        :func:`.camera.scene_camera`; the scene's own view keeps its offset and aim), or with the scene's own
        camera and its shots (``SHOTS``). The new camera snaps to its place at the next frame."""
        self.rig = scene_camera(self.sim.scene, None if name == SHOTS else name)
        self.view_name = name
        if not self._inside_needed() <= set(self._interiors):
            self._vehicle_fields()

    @property
    def follow(self) -> int:
        """The vehicle the camera rides with in the shot of its last update."""
        return self.rig.shot.rides

    @property
    def target(self) -> int:
        """The vehicle the camera looks at in the shot of its last update."""
        return self.rig.shot.target

    def _inside_needed(self) -> set:
        """The vehicles a shot of the camera looks out of (the driver's view): their interiors are drawn."""
        return {s.rides for s in self.rig.shots if s.view in INSIDE_VIEWS}

    def _vehicle_fields(self) -> None:
        """The vehicles: one merged mesh, posed on the host each frame (wheels turned by the odometer). A vehicle
        that a shot looks out of also holds its windscreen frame (:mod:`.interior`); the triangles drawn are
        those of the outside (``_layouts[None]``) or of the view from that vehicle's cabin (``_layouts[i]``)."""
        scene = self.sim.scene
        self._meshes = scene_meshes(scene)
        self._interiors = {}
        for i in sorted(self._inside_needed()):
            self._interiors[i] = interior_of(scene.vehicles[i], self._meshes[i])
            self._meshes[i] = self._interiors[i].mesh
        self._v_sizes = [len(m.verts) for m in self._meshes]
        vs, ns, cs, ids = merge([m[:4] for m in self._meshes])
        self._layouts = {None: self._triangles(None)}
        self._layouts.update({i: self._triangles(i) for i in self._interiors})
        self._layout = None
        self._v_frame = None  # this frame's vertices (local frame), for the lost-mesh check
        self._inside = None  # the vehicle whose cabin the camera looks out of this frame
        self._odometer = Odometer(self.sim.fleet.paths)
        if self._v is not None:  # the fields of the last call go back (the same sizes take them again)
            _POOL.give_back(self._v, self)
        self._v = v = _lease_vehicles(self, len(vs), max(len(tri) for tri in self._layouts.values()))
        # an explicit identity model matrix: see the module docstring (a plain scene.mesh can vanish)
        put_whole([v.cols, v.model], [cs, np.eye(4)[None]], np.float32)
        self._upload_layout(None)
        self._identity = host_buffer((1, 4, 4))  # the same, as GGUI's wrapper hands it over (never freed)
        self._identity[0] = np.eye(4, dtype=np.float32)

    def _triangles(self, inside) -> np.ndarray:
        """The merged mesh's indices drawn from outside (``inside`` None) or from the cabin of vehicle
        ``inside`` (its own triangles first, nearest first: the depth test then rejects what they hide before
        GGUI shades it)."""
        out, start = [], np.cumsum([0] + self._v_sizes)
        for i, m in enumerate(self._meshes):
            tri = self._interiors[i].triangles(i == inside) if i in self._interiors else m.idx
            out.append(np.asarray(tri, np.int64) + start[i])
        if inside is not None:
            out.insert(0, out.pop(inside))
        return np.concatenate(out)

    def _upload_layout(self, inside) -> None:
        ids = self._layouts[inside]
        full = np.zeros(self._v.idx.shape[0], np.int32)
        full[:len(ids)] = ids
        put_whole([self._v.idx], [full], np.float32)
        self._layout = inside

    def wheel_angles(self, t: float) -> list:
        """Per vehicle, its wheels' angles (rad) at time ``t``: distance driven / tire radius (rear wheels:
        times 1 + slip; :mod:`.wheels`)."""
        dist = self._odometer.at(t)
        return [wheel_angles(v, d, m.rear) for v, d, m in zip(self.sim.scene.vehicles, dist, self._meshes)]

    def posed_vehicles(self, poses, origin, t: float) -> list:
        """Per vehicle, its (vertices, normals) in the local frame at time ``t`` (float64); with
        ``self._meshes`` (triangles, owners) this is what GGUI draws."""
        return [pose_mesh(m, np.asarray(p.position, np.float64) - origin, p.heading, a)
                for m, p, a in zip(self._meshes, poses, self.wheel_angles(t))]

    def close(self) -> None:
        """Release the window and the imgui.ini GGUI left behind, give the buffers back to the pool (the next
        renderer of their sizes takes them, compiled), the vehicles' fields with them. It draws no more frames
        after this; the Simulation stays usable. Closing twice does nothing more."""
        self._win.release()
        _POOL.give_back(self._f, self)
        _POOL.give_back(self._v, self)
        self.hits.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -------------------------------------------------------------------------------------------- frame
    def view(self) -> View:
        """Advance the camera to ``sim.time``; return the view in local f32 coordinates:
        (eye, target, forward, right, up, heading). Calling it twice at the same time changes nothing."""
        sim = self.sim
        return look_at_time(self.rig, sim.vehicle_poses(), sim.time, sim.origin)

    def sun_direction(self, heading: float) -> np.ndarray:
        """Unit vector towards the sun (:func:`.camera.sun_direction`; ``heading``: the rig's)."""
        return sun_direction(heading, *self.sun)

    def _bucket(self, need: int) -> K.Bucket:
        cap = MIN_BUCKET
        while cap < need:
            cap *= 2
        cap = min(cap, max(self.n_rocks, 1))
        f = self._f
        if cap not in f.buckets:
            f.buckets[cap] = K.Bucket(cap, f.trees)
        return f.buckets[cap]

    def _mesh_bucket(self, need: int) -> MeshBucket:
        """A bucket for ``need`` rock meshes per level; without orientations (nothing to turn them by) a
        one-rock bucket that the rock pass compiles out: flying rocks stay particles."""
        f = self._f
        if not drawing.has_orientations(self.sim.world):
            if 0 not in f.mesh_buckets:
                f.mesh_buckets[0] = MeshBucket(1, on=False, trees=f.trees)
            return f.mesh_buckets[0]
        cap = f.mesh_cap  # only ever grows: each capacity compiles the rock pass anew (seconds)
        while cap < need:
            cap *= 2
        f.mesh_cap = cap = min(cap, max(self.n_rocks, 1))
        if cap not in f.mesh_buckets:
            f.mesh_buckets[cap] = MeshBucket(cap, trees=f.trees)
        return f.mesh_buckets[cap]

    def _frustum(self):
        return K.Frustum(tan_x=self.tan_x, tan_y=self.tan_y, sec_x=math.sqrt(1 + self.tan_x ** 2),
                         sec_y=math.sqrt(1 + self.tan_y ** 2), near=NEAR, far=self.draw_distance,
                         px_per_rad=self.px_per_rad)

    @staticmethod
    def _cam(eye, fwd, right, up):
        return K.CameraBasis(eye=_vec(eye), fwd=_vec(fwd), right=_vec(right), up=_vec(up))

    def _shade(self, sun) -> K.Shade:
        """The shadows' geometry for a sun direction (unit, towards the sun): see :class:`.kernels.Shade`."""
        sz = max(float(sun[2]), 0.05)  # the sun just above the horizon at the lowest: shadows 20 x as long
        horiz = math.hypot(float(sun[0]), float(sun[1]))
        away = (-float(sun[0]) / horiz, -float(sun[1]) / horiz) if horiz > 1e-9 else (1.0, 0.0)
        return K.Shade(z=self.ground_z - float(self.sim.origin[2]), shift=ti.Vector(self._shift(sun)),
                       away=ti.Vector(away), sin_el=sz / math.hypot(sz, horiz), contact_px=CONTACT_PX)

    @staticmethod
    def _shift(sun) -> tuple:
        """Where a point's shadow falls, per metre of its height above the ground: -sun_xy / sun_z."""
        sz = max(float(sun[2]), 0.05)
        return (-float(sun[0]) / sz, -float(sun[1]) / sz)

    def cull(self, eye, fwd, right, up, sun) -> int:
        """Cull the rocks; splat the resting ones ("splat" mode) and compact those GGUI draws into a bucket.
        Return how many GGUI draws (also ``self.last_count``). With active stepping the rocks are the active
        list's and those of the tile store's tiles in view (:mod:`.tiles`); ``tiles_in_view``: how many tiles
        the last pass visited (0 without a store)."""
        n = self.n_rocks
        self._drawn = None
        if n == 0:
            self.last_count = 0
            return 0
        w, h = self.resolution
        cam = self._cam(eye, fwd, right, up)
        size = K.Sizing(lod_px=self.lod_pixels, radius_scale=h / w)  # GGUI 1.7.4 draws particles w/h too large
        light = K.Light(sun=_vec(sun), ambient=ti.Vector(AMBIENT), sun_color=ti.Vector(SUN_COLOR))
        shade = self._shade(sun)
        tiles = ti.Vector([float(x) for x in self.sim.tile_shift()])
        need = max(int(self.last_count * 1.25), 1)
        need_meshes = max(self.last_meshes, 1)
        while True:
            bucket, meshes = self._bucket(need), self._mesh_bucket(need_meshes)
            K.rocks_pass(self.sim.world, self._buf, bucket, meshes, cam, self._frustum(), size, light, shade,
                         self._visible, tiles)
            count = int(self._buf.count[None])
            n_meshes = tuple(int(c) for c in self._buf.mesh_count.to_numpy())  # per level of detail
            if count <= bucket.cap and max(n_meshes) <= meshes.cap:
                break
            need, need_meshes = max(count, need), max(max(n_meshes), need_meshes)
            if self.rocks == "splat" or self.shadows:  # splats in the buffers already: clear them first
                K.clear_buffers(self._buf)
        if any(n_meshes):
            if self._protos is None:
                self._protos = shared_prototypes()
            expand(meshes, self._protos, *n_meshes, *meshes.vbo)
        self.last_count, self.last_meshes = count, max(n_meshes)
        self.tiles_in_view = int(self._visible.count[None]) if drawing.has_tiles(self.sim.world) else 0
        self._drawn = (bucket, count, meshes, n_meshes)
        return count + sum(n_meshes)

    def render_frame(self, view: View = None):
        """Draw the simulation's current state; return the upright image, (H, W, 3) uint8 (None in a shown
        window: the frame is declared there, for its owner to show). ``view``: look from there instead of the
        rig's view (the rig still advances: its heading turns the sun, see :meth:`sun_direction`).

        The returned array is reused by the next call: copy it to keep it.
        """
        t0 = time.perf_counter()
        sim = self.sim
        origin = np.asarray(sim.origin, np.float64)
        eye, target, fwd, right, up, heading = self.view()
        shot = self.rig.shot
        self._inside = shot.rides if view is None and shot.view in INSIDE_VIEWS else None
        if view is not None:
            eye, target, fwd, right, up = view[:5]
        sd = self.sun_direction(heading)
        t1 = time.perf_counter()
        self.cull(eye, fwd, right, up, sd)
        t2 = time.perf_counter()

        poses = sim.vehicle_poses()
        self.hits.update(sim)
        self._paint_sky_and_ground(eye, fwd, right, up, origin, poses, sd)
        if self._win.shown:  # nothing to read back: no glitch guard, no re-creation
            self._declare_ggui(eye, target, sd, origin, poses)
            self.frames_drawn += 1
            self.timings["cull"] += t2 - t1
            self.timings["draw"] += (t1 - t0) + (time.perf_counter() - t2)
            return None

        drawn = self._draw_ggui(eye, target, sd, origin, poses)
        for _ in range(GLITCH_RETRIES):
            # GGUI 1.7.4 on lavapipe now and then loses a whole renderable (seen: the vehicles' mesh) in one
            # frame: a collapse of the pixels GGUI drew, or a vehicle in view that hardly covers its screen box
            # (_vehicle_lost), is that, not the scene: draw the 3D layer again
            if drawn >= GLITCH_DROP * self._prev_drawn and not self._vehicle_lost(eye, fwd, right, up):
                break
            self.redraws += 1
            drawn = self._draw_ggui(eye, target, sd, origin, poses)
        self._prev_drawn = drawn
        self.frames_drawn += 1
        if self.window_every > 0 and self.frames_drawn % self.window_every == 0:
            self._win.close()
            self._win.open()
        t3 = time.perf_counter()
        self.timings["cull"] += t2 - t1
        self.timings["draw"] += (t1 - t0) + (t3 - t2)
        return self._out

    def _draw_ggui(self, eye, target, sd, origin, poses) -> int:
        """Declare the 3D layer, draw it, read it back over the background into ``self._out``; return how many
        pixels GGUI drew."""
        win = self._declare_ggui(eye, target, sd, origin, poses)
        raw = win.window.get_image_buffer_as_numpy()  # (W, H, 4) float32, y up; consumes the frame
        K.to_u8(raw, self._out, self._buf)
        self._raw = raw
        return int(self._buf.drawn_px[None])

    def _declare_ggui(self, eye, target, sd, origin, poses):
        """Declare the frame's GGUI layer (a shown window: over the background image); return the window."""
        win = self._win
        if not win.is_open:  # closed (or another renderer took over GGUI): reopen
            win.open()
        win.canvas.set_background_color(tuple(k / 255.0 for k in KEY))  # replaced by the background in to_u8
        if win.shown:
            win.canvas.set_image(self._buf.sky)
        scene = win.scene
        cam = self._ggui_camera
        cam.position(*(float(x) for x in eye))
        cam.lookat(*(float(x) for x in target))
        cam.up(*GL_UP)
        scene.set_camera(cam)
        scene.ambient_light(AMBIENT)
        scene.point_light(tuple(float(x) for x in eye + 2000.0 * sd), SUN_COLOR)
        self._draw_vehicles(scene, origin, poses)
        if self._drawn is not None:
            bucket, count, meshes, n_meshes = self._drawn
            if count > 0:
                scene.particles(bucket.pos, 0.03, per_vertex_color=bucket.col, per_vertex_radius=bucket.rad,
                                index_count=count)
            self._draw_rock_meshes(scene, meshes, n_meshes)
        self.hits.draw(scene, poses, origin, eye, self.px_per_rad, self.resolution[1] / self.resolution[0],
                       self._inside)
        self._overlays.draw(scene, self.sim, origin, self.ground_z)
        self._dust = draw_dust(getattr(self, "_dust", None), scene, self.sim, origin, self.horizon)  # render/dust.py
        win.canvas.scene(scene)
        return win

    def _draw_rock_meshes(self, scene, meshes, counts) -> None:
        """The flying rocks' meshes (:mod:`.tumbling`), a mesh per level of detail, their vertices transformed in
        a kernel and already in GGUI's layout: handed to GGUI's own scene as the wrapper's ``mesh_instance``
        would (one identity instance; see the module docstring), minus its repacking of the whole field."""
        for lod, n in enumerate(counts):
            if n > 0:
                vbo = meshes.vertices(lod, n)
                scene.scene.mesh_instance(get_field_info(vbo), True, get_field_info(None), (0.5, 0.5, 0.5), False,
                                          get_field_info(self._identity), 1, 0, len(vbo), 0, len(vbo), 0, False)

    def _vehicle_lost(self, eye, fwd, right, up) -> bool:
        """True if a vehicle in full view (in front of the camera, its screen box at least 3 x 3 pixels and
        inside the image) has almost no pixel drawn by GGUI inside its screen box: its mesh was lost. (A
        vehicle covers most of its box; flying rocks in front of it only a few pixels: below
        LOST_COVERAGE of the box counts as lost.)"""
        if self._v_frame is None or self._wireframe():  # see-through: nothing to measure
            return False
        W, H = self.resolution
        key = np.array(KEY, np.float32) / 255.0
        start = 0
        for nv in self._v_sizes:
            d = self._v_frame[start:start + nv].astype(np.float64) - eye
            start += nv
            z = d @ fwd
            if z.min() < 0.5 or z.min() > self.draw_distance:
                continue
            sx = (d @ right / (z * self.tan_x) + 1.0) * 0.5 * W
            sy = (d @ up / (z * self.tan_y) + 1.0) * 0.5 * H  # rows of the read-back: 0 = bottom
            x0, x1, y0, y1 = (int(math.floor(v)) for v in (sx.min(), sx.max(), sy.min(), sy.max()))
            if x0 < 0 or y0 < 0 or x1 >= W or y1 >= H or x1 - x0 < 3 or y1 - y0 < 3:
                continue
            box = self._raw[x0 + 1:x1, y0 + 1:y1, :3]
            drawn = np.any(np.abs(box - key) >= 0.5 / 255.0, axis=2)
            if drawn.mean() < LOST_COVERAGE:
                return True
        return False

    # -------------------------------------------------------------------------------------------- parts
    def _shadow_casters(self, poses, origin, sun_dir) -> int:
        """Upload the vehicles' footprints and heights (local frame) for their shadows; return how many."""
        cars = np.zeros((MAX_CARS, 11), np.float32)
        shift = np.array(self._shift(sun_dir))
        k = 0
        for p, v in zip(poses, self.sim.scene.vehicles):
            if k == MAX_CARS:
                break
            loc = np.asarray(p.position, np.float64) - origin
            top = 0.8 * v.tire_radius + v.height
            soft = 0.35 + 0.4 * v.width  # of the contact shadow
            mid = loc[:2] + 0.5 * top * shift  # the sun shadow's middle, and a circle round both shadows
            reach = 0.5 * math.hypot(v.length, v.width) + 0.5 * top * float(np.hypot(*shift)) + max(soft, 0.5)
            cars[k] = (loc[0], loc[1], math.cos(p.heading), math.sin(p.heading), 0.5 * v.length, 0.5 * v.width,
                       soft, top, mid[0], mid[1], reach * reach)
            k += 1
        self._buf.cars.from_numpy(cars)
        return k

    def _paint_sky_and_ground(self, eye, fwd, right, up, origin, poses, sun_dir) -> None:
        period = 2.0 * self.tile
        wrap = (float(np.mod(origin[0], period)), float(np.mod(origin[1], period)))
        light = tuple(a + l * max(float(sun_dir[2]), 0.0) for a, l in zip(AMBIENT, SUN_COLOR))
        n_cars = self._shadow_casters(poses, origin, sun_dir)
        ground = K.Ground(z=self.ground_z - float(origin[2]), wrap=ti.Vector(wrap), tile=self.tile,
                          haze_dist=HAZE * self.draw_distance, shift=ti.Vector(self._shift(sun_dir)))
        umbra = tuple(a / l for a, l in zip(AMBIENT, light))
        palette = K.Palette(ground_a=ti.Vector(GROUND_A), ground_b=ti.Vector(GROUND_B), light=ti.Vector(light),
                            sky=ti.Vector(self.background), horizon=ti.Vector(self.horizon), umbra=ti.Vector(umbra))
        K.paint_ground(self._buf, self._cam(eye, fwd, right, up), self._frustum(), ground, palette, n_cars)

    def _draw_vehicles(self, scene, origin, poses) -> None:
        posed = self.posed_vehicles(poses, origin, self.sim.time)
        out_v = np.concatenate([v for v, _ in posed])
        self._v_frame = out_v
        # both in one launch (engine/transfer.py): one compile a renderer, not one per field
        v = self._v
        put_whole([v.verts, v.norms], [out_v, np.concatenate([n for _, n in posed])], np.float32)
        if self._inside != self._layout:
            self._upload_layout(self._inside)
        scene.mesh_instance(v.verts, indices=v.idx, normals=v.norms, per_vertex_color=v.cols, transforms=v.model,
                            index_count=len(self._layouts[self._layout]), show_wireframe=self._wireframe())

    def _wireframe(self) -> bool:
        """Vehicles are drawn as wireframes while an overlay of what is under them is on: the tire rays, the
        hash cells, the tread patches (which lie inside the tires: a solid tire hides them entirely)."""
        f = self.flags
        return bool(f.tire_rays or f.hash_cells or f.tread_patch)


class _Fields:
    """A renderer's buffers for a resolution, rock mode, shadows and tile store: the background image, splat
    buffers and shadows (:class:`.kernels.Buffers`), the tile store's slots in view (:class:`.tiles.Visible`),
    the compact buckets of the rocks drawn as particles and as meshes (by capacity), and the overlays' lines.
    Leased from :data:`_POOL`: the next Renderer of the same sizes on a pooled World (engine/world.py) then
    starts with its rock pass and ground kernels compiled (a new set costs seconds of compiling)."""

    def __init__(self, w: int, h: int, splat: bool, shadows: bool, n_slots: int):
        self.trees, self.owner = FieldTrees(), None
        self.buf = K.Buffers(w, h, splat, MAX_CARS, shadows, self.trees)
        self.visible = K.Visible(n_slots, self.trees)
        self.buckets, self.mesh_buckets, self.mesh_cap = {}, {}, MIN_MESHES
        self.overlays = Overlays(SimpleNamespace(), self.trees)


class _Vehicles:
    """The vehicles' merged mesh for ``nv`` vertices and ``ni`` indices: positions and normals (posed each
    frame), colours, the triangles' indices and GGUI's model matrix. Leased from :data:`_POOL` like
    :class:`_Fields`: a renderer of the same vehicles then uploads and draws them with kernels compiled (the
    uploads' and GGUI's copies into its vertex buffers). Every field is written before it is drawn."""

    def __init__(self, nv: int, ni: int):
        self.trees, self.owner = FieldTrees(), None
        t = self.trees
        self.verts, self.norms, self.cols = (t.vector(3, ti.f32, nv) for _ in range(3))
        self.idx = t.scalar(ti.i32, ni)
        self.model = t.matrix(4, 4, ti.f32, 1)


_POOL = Pool()


def _lease_vehicles(owner, nv: int, ni: int) -> _Vehicles:
    """A free set of vehicle fields of these sizes, or a new one."""
    return _POOL.lease(owner, ("vehicles", nv, ni), lambda: _Vehicles(nv, ni))


def _lease(owner, w, h, splat, shadows, n_slots) -> _Fields:
    """A free set of buffers of these sizes, cleared, or a new one."""
    return _POOL.lease(owner, (w, h, splat, shadows, n_slots), lambda: _Fields(w, h, splat, shadows, n_slots),
                       lambda f: K.clear_buffers(f.buf))
