"""USD export (usd-core's ``pxr``): a stage that Houdini, Omniverse, Unreal and Blender (4.4+) open.

Stage: Z up, 1 metre per unit, timeCodesPerSecond = framesPerSecond = fps, time codes 0 .. frames - 1 (time
code f is frame f, t = f / fps). Prims::

    /World                          Xform, the default prim
      Looks/DisplayColor            Material: a UsdPreviewSurface whose diffuse colour is the displayColor primvar
      Looks/Glass                   Material: the same, with opacity GLASS_OPACITY (the windows)
      Ground/Plane                  Mesh: a rectangle around every vehicle's path (its Xform: double translate)
      Bed                           Xform, xformOp:translate double, time-sampled: the floating origin
        Rocks                       PointInstancer, positions float32 relative to Bed
        Impacts                     Points: the frame's impacts (only when the run records them; below)
          Prototypes/rock_<k>_<j>   Mesh: low-poly rocks of mean radius 1, shape k in tint j (only instanced)
      Vehicles/<name>               Xform: translate (double, world) and rotateZ (heading, deg), time-sampled
        Body                        Mesh: the body's parts (motion/bodies.py) with the faces the renderer draws
        Glass                       Mesh: their windows (bound to Looks/Glass: a camera in the cabin sees out)
        Wheel_<FL|FR|RL|RR>         Xform: translate, rotateY (spin, deg, time-sampled); its Tire: a cylinder
      Camera                        Camera: xformOp:transform (double), time-sampled; the scene's camera
                                    ([camera] and its shots; at a cut the shot before is held, as below)

Per frame the PointInstancer has protoIndices, ids (int64), positions, orientations (quath), scales
(the rock radius on each axis), velocities (m/s, for motion blur), angularVelocities (deg/s) and
primvars:displayColor (per instance) of the rocks written in that frame, and an extent.

Impacts (a run with ``[effects] impacts``: frames carry ``impacts``, app/export.py): the Points prim holds, at
time code f, the contact points of the hits since frame f - 1 (relative to Bed, like the rocks: Bed.translate +
point is the world position where the stone touched the body, the vehicle placed at the time of the hit), with
``normals`` (the body's outward normal there, world axes), ``widths`` (the stone's diameter) and vertex
primvars ``energy`` (float, J, 1/2 m |u|^2 of the relative motion), ``damage``
(int, index into the prim's customData ``taichi_rocks:damage_classes``: mark, chip, crack), ``class`` (token,
the same as a name), ``vehicle`` (int, the vehicle hit, scene order; customData ``taichi_rocks:vehicles``),
``part`` (token, motion/bodies.py LABELS), ``normalSpeed`` (float, m/s), ``rock`` (int, the stone's id: a
stone bouncing twice is there twice) and ``time`` (double, s). Every frame
has a sample (empty without hits) and a frame with hits also an empty one at f - STEP_HOLD, so that no tool
interpolates one frame's hits into another's: a hit shows in the frame it happens in, where sparks or a decal
can be put.

Colours (output/looks.py): every mesh has a displayColor primvar, the renderer's colours: the rocks' tints
(per instance on the instancer, and in the prototype's tint: prototype k * TINTS + j is shape k in palette
tint j, for tools such as Blender 4.5 that read neither per-instance primvars nor displayColor alone), the
vehicles' bodies in their scene colour, tires per face as the renderer's tread and rim, the ground. Each mesh
is bound to one material reading displayColor (UsdPrimvarReader_float3), so that an import looks like the
render before anyone assigns materials. displayColor is linear, the renderer's display colours converted by
the sRGB transfer function (output/looks.py ``linear``).

Precision. float32 positions far from the world origin would be coarse (8 mm at 100 km), so they are local
to the Bed Xform, whose translate (double) is the engine's floating origin: the origin the engine computes
in, within 128 m of the bed and moving in exact 64 m steps. A local position is then the engine's own float32
value, and Bed.translate + local is the simulated world position. Because the origin is still between its
steps, a rock's local velocity is its world velocity (a frame following the bed centre would move, and
motion blur from velocities would smear resting rocks along the bed's motion). Where the origin steps
between frames f - 1 and f, the frame is also written at time code f - STEP_HOLD relative to the old
origin (the Bed translate holding the old value): a tool interpolating the samples linearly then composes
the interpolated world positions, and one extrapolating from a sample with its velocities (motion blur)
stays in that sample's frame, instead of sliding the rocks across the step (64 m or more) in between (only
extrapolation from the extra sample, within STEP_HOLD of the step, still sees the slide). A camera cut (a
[[camera.shot]] starting) is held the same way: the camera of the previous frame is written again at
f - STEP_HOLD, so that a tool interpolating between the two shots cuts instead of flying the camera across.

The layer is saved after every frame: a crate (.usdc) file saved again to the same file appends the new time
samples, and the samples already written are no longer held in memory, so memory stays flat.
"""

from __future__ import annotations

import errno
import math

import numpy as np

from .dust import write_dust
from .formats import FileWriter
from .instances import PROTOTYPES
from ..config.impacts import DAMAGE_CLASSES
from ..motion.bodies import FACE_CORNERS, FACES, LABELS, body_parts
from .looks import GROUND_COLOR, TINTS, TIRE_COLOR, TREAD_COLOR, WHEEL_SIDE_COLOR, linear, part_faces, tint_palette
from .shapes import camera_matrix, cylinder_mesh, rock_prototype

try:
    from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdShade, Vt
except ImportError:  # usd-core is optional: UsdWriter.check_target says how to install it
    Gf = Sdf = Tf = Usd = UsdGeom = UsdShade = Vt = None

__all__ = ["UsdWriter", "STEP_HOLD", "USD_SUFFIXES", "ground_extent", "usd_write_error"]

STEP_HOLD = 1e-4  # time codes before a step of the origin at which the old origin is held
MATERIAL = "/World/Looks/DisplayColor"
GLASS = "/World/Looks/Glass"
GLASS_OPACITY = 0.35  # the windows: see-through, so that the driver's and bonnet shots look out of the cabin
WHEELS = (("FL", 0.5, 0.5), ("FR", 0.5, -0.5), ("RL", -0.5, 0.5), ("RR", -0.5, -0.5))
USD_SUFFIXES = (".usdc", ".usd")  # crate files: saving again appends, so a long export streams


_ERRNO = {"No space left": errno.ENOSPC, "Permission denied": errno.EACCES, "Read-only file system": errno.EROFS,
          "Disk quota": errno.EDQUOT}


def usd_write_error(exc, out) -> OSError:
    """pxr's error (a Tf.ErrorException: a line per error, with the library's internals) as one OSError naming
    ``out`` and the first error's own words (``Error occurred writing file: No space left on device``)."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    cause = lines[0] if lines else type(exc).__name__
    for ln in lines:
        if " : '" in ln:
            cause = ln.split(" : '", 1)[1].rstrip("'")
            break
    code = next((n for words, n in _ERRNO.items() if words in cause), errno.EIO)
    return OSError(code, f"cannot write the USD file: {cause}", str(out))


def ground_extent(fleet, scene, frames: int, fps: float):
    """(centre XY, half sides) of a ground rectangle around every vehicle's path over the export, with room
    for the bed and the view around it."""
    pts = np.array([p.position[:2] for f in range(max(frames, 1)) for p in fleet.poses(f / fps)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = float(scene.bed.radius) + float(scene.render.draw_distance)
    return (lo + hi) / 2.0, (hi - lo) / 2.0 + margin


def _material(stage, path: str = MATERIAL, opacity=None):
    """A material of the stage: a UsdPreviewSurface whose diffuse colour reads the displayColor primvar (and
    ``opacity``, if given)."""
    mat = UsdShade.Material.Define(stage, path)
    surface = UsdShade.Shader.Define(stage, f"{path}/Surface")
    surface.CreateIdAttr("UsdPreviewSurface")
    if opacity is not None:
        surface.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(opacity))
    reader = UsdShade.Shader.Define(stage, f"{path}/DisplayColor")
    reader.CreateIdAttr("UsdPrimvarReader_float3")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("displayColor")
    reader.CreateInput("fallback", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(0.5, 0.5, 0.5))
    color = reader.CreateOutput("result", Sdf.ValueTypeNames.Float3)
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(color)
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.8)
    mat.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    return mat


def _face_normals(points, counts, indices) -> np.ndarray:
    """Per face vertex (faceVarying), its face's unit normal (Newell's method), float32."""
    p = np.asarray(points, np.float64)
    out, k = [], 0
    for c in np.asarray(counts):
        ring = p[indices[k:k + c]]
        nxt = np.roll(ring, -1, axis=0)
        n = np.cross(ring, nxt).sum(axis=0)
        out.append(np.tile(n / np.linalg.norm(n), (c, 1)))
        k += c
    return np.ascontiguousarray(np.concatenate(out), np.float32)


def _mesh(stage, path: str, mesh, color, material: str = MATERIAL) -> UsdGeom.Mesh:
    """A mesh bound to the stage's material; ``color``: one rgb (constant) or one per face (uniform), display
    values (written linear: output/looks.py)."""
    points, counts, indices = mesh
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points, np.float32)))
    m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(counts, np.int32)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(indices, np.int32)))
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    m.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(_face_normals(points, counts, indices)))
    m.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)  # flat faces, as the renderer shades them
    lo, hi = points.min(axis=0), points.max(axis=0)
    m.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    color = linear(color).astype(np.float32).reshape(-1, 3)
    per_face = len(color) > 1
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                               UsdGeom.Tokens.uniform if per_face else UsdGeom.Tokens.constant)
    pv.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(color)))
    UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(UsdShade.Material.Get(stage, material))
    return m


def _prim_names(names) -> list:
    """Valid, unique prim names for the scene's vehicle names."""
    out = []
    for name in names:
        base = Tf.MakeValidIdentifier(str(name))
        candidate, k = base, 1
        while candidate in out:
            candidate, k = f"{base}_{k}", k + 1
        out.append(candidate)
    return out


def _body_meshes(spec) -> dict:
    """The body of vehicle ``spec`` as two meshes, "Body" and "Glass": each part of motion/bodies.py with the
    faces the renderer draws (output/looks.py part_faces), per face its colour; quads wound counter-clockwise
    seen from outside their (convex) part."""
    body = body_parts(spec)
    out = {"Body": ([], []), "Glass": ([], [])}
    for part in body.parts:
        corners = part.corners()
        centre = corners.mean(axis=0)
        for face, (color, glass) in part_faces(body.kind, part.name, spec.color).items():
            quad = corners[list(FACE_CORNERS[FACES.index(face)])]
            n = np.cross(quad[1] - quad[0], quad[2] - quad[0]) + np.cross(quad[2] - quad[0], quad[3] - quad[0])
            if n @ (quad.mean(axis=0) - centre) < 0:
                quad = quad[::-1]
            out["Glass" if glass else "Body"][0].append(quad)
            out["Glass" if glass else "Body"][1].append(color)
    return {name: ((np.concatenate(q).astype(np.float32), np.full(len(q), 4, np.int32),
                    np.arange(4 * len(q), dtype=np.int32)), np.array(c)) for name, (q, c) in out.items() if q}


def _tire_colors(faces: int) -> np.ndarray:
    """Per face of output/shapes.py's cylinder (its tread quads, then its two caps): the tread blocks alternating
    between the renderer's two rubbers, the sides in the mean colour of its rim."""
    tread = [TREAD_COLOR if k % 2 else TIRE_COLOR for k in range(faces - 2)]
    return np.array(tread + [WHEEL_SIDE_COLOR] * 2, np.float32)


class UsdWriter(FileWriter):
    """``--format usd``: one stage (see the module docstring), written under a temporary name ending in .usdc
    and renamed when complete (output/formats.py FileWriter)."""

    name = "usd"
    default_name = "{scene}.usdc"
    suffixes = USD_SUFFIXES
    temp_suffix = ".part.usdc"

    @classmethod
    def check_target(cls, out, overwrite: bool) -> None:
        if Usd is None:
            raise ValueError("--format usd needs the usd-core package: pip install usd-core "
                             "(or pip install 'taichi-rocks[usd]')")
        super().check_target(out, overwrite)

    def __init__(self, out, run):
        super().__init__(out, run)
        scene, fps, frames = run.scene, run.fps, run.frames
        info = {"scene": scene.name, "seed": int(scene.seed), "fps": float(fps), "dt": float(run.dt),
                "frames": int(frames), "only": run.only, "crop": float(run.crop) if run.crop is not None else 0.0}
        try:
            self._stage(scene, fps, frames, ground_extent(run.fleet, scene, frames, fps), info)
        except Tf.ErrorException as e:
            self.abort()
            raise usd_write_error(e, self.out) from None
        except BaseException:
            self.abort()
            raise

    def _stage(self, scene, fps: float, frames: int, ground: tuple, info: dict) -> None:
        self.layer = Sdf.Layer.CreateNew(str(self.tmp))
        self.stage = stage = Usd.Stage.Open(self.layer)
        stage.SetMetadata("comment", f"taichi-rocks export of scene {scene.name!r}")
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(float(fps))
        stage.SetFramesPerSecond(float(fps))
        stage.SetStartTimeCode(0.0)
        stage.SetEndTimeCode(float(max(frames - 1, 0)))
        world = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(world.GetPrim())
        self.layer.customLayerData = {k: v for k, v in info.items()}
        _material(stage)
        _material(stage, GLASS, GLASS_OPACITY)
        self._ground(scene, *ground)
        bed = UsdGeom.Xform.Define(stage, "/World/Bed")
        self.origin_op = bed.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)
        self._rocks()
        self._vehicles(scene)
        self._camera_prim(scene)
        self.last_origin = self.last_camera = None
        self.impacts = None  # the Impacts prim's attributes, made at the first frame that has impacts
        self.vehicle_names = [str(v.name) for v in scene.vehicles]
        self.layer.Save()

    # -------------------------------------------------------------------------------------- static parts
    def _ground(self, scene, center, half) -> None:
        xf = UsdGeom.Xform.Define(self.stage, "/World/Ground")
        xf.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(float(center[0]), float(center[1]),
                                                                        float(scene.world.ground_z)))
        hx, hy = (float(h) for h in half)
        quad = (np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]], np.float32),
                np.array([4], np.int32), np.array([0, 1, 2, 3], np.int32))
        _mesh(self.stage, "/World/Ground/Plane", quad, GROUND_COLOR)

    def _rocks(self) -> None:
        pi = UsdGeom.PointInstancer.Define(self.stage, "/World/Bed/Rocks")
        UsdGeom.Scope.Define(self.stage, "/World/Bed/Rocks/Prototypes")
        palette = tint_palette()
        protos = [_mesh(self.stage, f"/World/Bed/Rocks/Prototypes/rock_{k}_{j}", rock_prototype(k), palette[j])
                  for k in range(PROTOTYPES) for j in range(TINTS)]
        pi.CreatePrototypesRel().SetTargets([p.GetPath() for p in protos])
        colors = UsdGeom.PrimvarsAPI(pi).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                                       UsdGeom.Tokens.vertex)
        self.attrs = {"proto": pi.CreateProtoIndicesAttr(), "ids": pi.CreateIdsAttr(),
                      "positions": pi.CreatePositionsAttr(), "orientations": pi.CreateOrientationsAttr(),
                      "scales": pi.CreateScalesAttr(), "velocities": pi.CreateVelocitiesAttr(),
                      "angular": pi.CreateAngularVelocitiesAttr(), "extent": pi.CreateExtentAttr(),
                      "colors": colors}

    def _vehicles(self, scene) -> None:
        self.vehicle_ops = []
        UsdGeom.Scope.Define(self.stage, "/World/Vehicles")
        for spec, name in zip(scene.vehicles, _prim_names(v.name for v in scene.vehicles)):
            root = f"/World/Vehicles/{name}"
            xf = UsdGeom.Xform.Define(self.stage, root)
            xf.GetPrim().SetCustomDataByKey("taichi_rocks:name", str(spec.name))
            ops = [xf.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble),
                   xf.AddRotateZOp(UsdGeom.XformOp.PrecisionDouble)]
            r = float(spec.tire_radius)
            for name, (mesh, colors) in _body_meshes(spec).items():
                _mesh(self.stage, f"{root}/{name}", mesh, colors, GLASS if name == "Glass" else MATERIAL)
            tire = cylinder_mesh(r, float(spec.tire_width))
            tire_colors = _tire_colors(len(tire[1]))
            for label, sx, sy in WHEELS:
                wheel = UsdGeom.Xform.Define(self.stage, f"{root}/Wheel_{label}")
                wheel.AddTranslateOp().Set(Gf.Vec3f(sx * spec.wheelbase, sy * spec.track, r))
                ops.append(wheel.AddRotateYOp(UsdGeom.XformOp.PrecisionDouble))
                _mesh(self.stage, f"{root}/Wheel_{label}/Tire", tire, tire_colors)
            self.vehicle_ops.append(ops)

    def _camera_prim(self, scene) -> None:
        cam = UsdGeom.Camera.Define(self.stage, "/World/Camera")
        w, h = scene.render.resolution
        focal = 35.0  # the field of view depends only on aperture / focal length (same units)
        vertical = 2.0 * focal * math.tan(math.radians(scene.camera.fov) / 2.0)
        cam.CreateFocalLengthAttr(focal)
        cam.CreateVerticalApertureAttr(vertical)
        cam.CreateHorizontalApertureAttr(vertical * w / h)
        cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, max(1000.0, 10.0 * float(scene.render.draw_distance))))
        self.camera_op = cam.AddTransformOp()

    # -------------------------------------------------------------------------------------- per frame
    def write(self, fr: dict) -> None:
        """One frame (output/formats.py); saved to disk before returning. pxr's errors as one OSError."""
        try:
            self._write(fr)
        except Tf.ErrorException as e:
            raise usd_write_error(e, self.out) from None

    def _write(self, fr: dict) -> None:
        t = float(fr["frame"])
        origin = Gf.Vec3d(*map(float, fr["origin"]))
        if self.last_origin is not None and origin != self.last_origin:  # the origin steps: hold it (see above)
            old = np.array(self.last_origin, np.float64)
            self.origin_op.Set(self.last_origin, t - STEP_HOLD)
            self._rock_samples(fr, (fr["world"] - old).astype(np.float32), t - STEP_HOLD)
        self.origin_op.Set(origin, t)
        self.last_origin = origin
        self._rock_samples(fr, fr["local"], t)
        veh = fr["vehicles"]
        for i, ops in enumerate(self.vehicle_ops):
            ops[0].Set(Gf.Vec3d(*map(float, veh["positions"][i])), t)
            ops[1].Set(math.degrees(float(veh["headings"][i])), t)
            for j, (label, sx, _) in enumerate(WHEELS):
                ops[2 + j].Set(math.degrees(float(veh["front" if sx > 0 else "rear"][i])), t)
        camera = Gf.Matrix4d(*map(float, camera_matrix(*fr["camera"]).reshape(-1)))
        if fr.get("cut") and self.last_camera is not None:  # a cut: the shot before holds up to it
            self.camera_op.Set(self.last_camera, t - STEP_HOLD)
        self.camera_op.Set(camera, t)
        self.last_camera = camera
        if "impacts" in fr:
            self._impact_samples(fr["impacts"], np.asarray(fr["origin"], np.float64), t)
        if "dust" in fr:  # [effects] dust: output/dust.py
            self.dust = write_dust(self.stage, getattr(self, "dust", None), fr["dust"], fr["origin"], t, self.run.scene.dust)
        self.layer.Save()

    def _impact_prim(self) -> dict:
        pts = UsdGeom.Points.Define(self.stage, "/World/Bed/Impacts")
        prim = pts.GetPrim()
        prim.SetCustomDataByKey("taichi_rocks:damage_classes", Vt.StringArray(list(DAMAGE_CLASSES)))
        prim.SetCustomDataByKey("taichi_rocks:vehicles", Vt.StringArray(self.vehicle_names))
        api = UsdGeom.PrimvarsAPI(pts)
        vertex = UsdGeom.Tokens.vertex
        names = Sdf.ValueTypeNames
        return {"points": pts.CreatePointsAttr(), "normals": pts.CreateNormalsAttr(),
                "widths": pts.CreateWidthsAttr(), "extent": pts.CreateExtentAttr(),
                "energy": api.CreatePrimvar("energy", names.FloatArray, vertex),
                "damage": api.CreatePrimvar("damage", names.IntArray, vertex),
                "class": api.CreatePrimvar("class", names.TokenArray, vertex),
                "vehicle": api.CreatePrimvar("vehicle", names.IntArray, vertex),
                "part": api.CreatePrimvar("part", names.TokenArray, vertex),
                "normalSpeed": api.CreatePrimvar("normalSpeed", names.FloatArray, vertex),
                "rock": api.CreatePrimvar("rock", names.IntArray, vertex),
                "time": api.CreatePrimvar("time", names.DoubleArray, vertex)}

    def _impact_samples(self, imp: dict, origin: np.ndarray, t: float) -> None:
        """The Impacts prim's samples at time code ``t``: the hits of ``imp`` (app/export.py impact_frame)."""
        if self.impacts is None:
            self.impacts = self._impact_prim()
        a, ev = self.impacts, imp["events"]
        if len(ev):  # nothing of the frames before is interpolated into this one
            self._impact_values(a, ev[:0], np.empty((0, 3)), np.empty((0, 3)), t - STEP_HOLD)
        self._impact_values(a, ev, np.asarray(imp["world"], np.float64) - origin, imp["normals"], t)

    @staticmethod
    def _impact_values(a: dict, ev, local, normals, t: float) -> None:
        # fresh arrays: a one-element view of a structured array's field exports a buffer format pxr refuses
        col = lambda x, dt: np.array(x, dt, copy=True)
        local = col(np.asarray(local).reshape(-1, 3), np.float32)
        a["points"].Set(Vt.Vec3fArray.FromNumpy(local), t)
        a["normals"].Set(Vt.Vec3fArray.FromNumpy(col(np.asarray(normals).reshape(-1, 3), np.float32)), t)
        a["widths"].Set(Vt.FloatArray.FromNumpy(col(2.0 * ev["radius"], np.float32)), t)
        for key, field in (("energy", "energy"), ("normalSpeed", "normal_speed")):
            a[key].Set(Vt.FloatArray.FromNumpy(col(ev[field], np.float32)), t)
        for key in ("damage", "vehicle", "rock"):
            a[key].Set(Vt.IntArray.FromNumpy(col(ev[key], np.int32)), t)
        a["class"].Set(Vt.TokenArray([DAMAGE_CLASSES[int(k)] for k in ev["damage"]]), t)
        a["part"].Set(Vt.TokenArray([LABELS[int(k)] for k in ev["part"]]), t)
        a["time"].Set(Vt.DoubleArray.FromNumpy(col(ev["time"], np.float64)), t)
        lo, hi = (local.min(axis=0), local.max(axis=0)) if len(local) else (np.zeros(3), np.zeros(3))
        a["extent"].Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]), t)

    def _rock_samples(self, fr: dict, local: np.ndarray, t: float) -> None:
        """The PointInstancer's samples at time code ``t``: the rocks of ``fr`` at ``local`` positions."""
        a = self.attrs
        proto = np.asarray(fr["proto"], np.int32) * TINTS + np.asarray(fr["tint"], np.int32)
        a["proto"].Set(Vt.IntArray.FromNumpy(np.ascontiguousarray(proto)), t)
        a["colors"].Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(linear(fr["tints"]), np.float32)), t)
        a["ids"].Set(Vt.Int64Array.FromNumpy(np.ascontiguousarray(fr["ids"], np.int64)), t)
        a["positions"].Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(local, np.float32)), t)
        a["orientations"].Set(Vt.QuathArray.FromNumpy(np.ascontiguousarray(fr["orientations"], np.float16)), t)
        scales = np.repeat(np.asarray(fr["radii"], np.float32)[:, None], 3, axis=1)
        a["scales"].Set(Vt.Vec3fArray.FromNumpy(scales), t)
        a["velocities"].Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(fr["velocities"], np.float32)), t)
        omega = np.degrees(np.asarray(fr["angular_velocities"], np.float64)).astype(np.float32)
        a["angular"].Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(omega)), t)
        if len(local):
            r = 1.3 * float(np.max(fr["radii"]))  # the prototypes reach a little beyond radius 1
            lo, hi = local.min(axis=0) - r, local.max(axis=0) + r
        else:
            lo = hi = np.zeros(3)
        a["extent"].Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]), t)

    def close(self) -> int:
        try:
            self.layer.Save()
        except Tf.ErrorException as e:
            raise usd_write_error(e, self.out) from None
        self._release()
        return super().close()

    def abort(self) -> None:
        self._release()
        super().abort()

    def _release(self) -> None:
        """Drop the stage, its layer and the handles into it (the layer is freed with the last one)."""
        self.stage = self.layer = None
        self.attrs, self.vehicle_ops, self.camera_op, self.origin_op = {}, [], None, None
        self.impacts = None
