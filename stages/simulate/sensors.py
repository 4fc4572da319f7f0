"""Cameras: Newton ``SensorCamera`` RGB, depth and segmentation for a robot's head and wrist
cameras and fixed third-person cameras, with intrinsics, extrinsics and the scene's lights.

Conventions: a camera frame looks along its local -Z with +Y up and +X right (USD/OpenGL, what
SensorCamera uses); :attr:`CameraFrame.extrinsics` gives camera-to-world 4x4 in that convention
and :meth:`CameraFrame.extrinsics_opencv` the world-to-camera 4x4 in the OpenCV convention
(+Z forward, +Y down). Depth is the planar (forward) depth [m] along the optical axis, 0 where a
ray hit nothing. Segmentation is the model shape index per pixel (-1 for no hit) and its
semantic label through ``Sim.shape_label`` (UsdSemantics labels read when the scene was loaded;
"robot" for the robot).

Lights. SensorCamera renders directional lights, spot lights and point lights (an internal type
without a spot cone) with Lambert shading, a falloff ``1 / (1 + 0.02 d^2)`` for local lights,
optional shadows, and hemispheric ambient light; its output saturates at 1. Newton 1.8 does not
import UsdLux lights itself, so :func:`read_usd_lights` reads them and :func:`apply_lights` maps
them photometrically, with the scene stage's conventions (``stages.scene.lighting``):

==================  =========================================================================
UsdLux              renderer
==================  =========================================================================
DistantLight        directional light along the light's -Z, shadows on;
                    illuminance E = intensity * 2^exposure [lux]
SphereLight         point light at its position (spot light if ShapingAPI cone < 90 deg);
                    luminous intensity I = intensity * 2^exposure * pi r^2 [cd]
RectLight/DiskLight spot light at its position along its -Z (the renderer's cone is fixed,
                    about 30 deg); I = intensity * 2^exposure * area [cd]
CylinderLight       point light, I as for a sphere of the cylinder's radius
DomeLight           ambient sky colour, E = pi * intensity * 2^exposure [lux] (textures ignored)
==================  =========================================================================

``inputs:normalize`` (on) divides a local light's luminance by its surface area (4 pi r^2 for a
sphere, w h, pi r^2, 2 pi r length for rect, disk and cylinder lights), as UsdLux defines it (what
Blender's exporter writes). The scene stage authors physical intensities and one common
``inputs:exposure`` on every light (``stages.scene.lighting.SCENE_EXPOSURE``; the dome's is in
its intensity); the values here are UsdLux's, exposure included, so ``exposure_lux`` is in those
units too, and the automatic exposure divides the common factor out.

Exposure: renderer value 1 is the illuminance ``exposure_lux``; by default (auto) the indoor
illuminance, i.e. the sum of the local lights' E at ``REFERENCE_DISTANCE`` (I / d^2) and the dome's
E, or the distant lights' E when there is nothing else; sunlight through a window then saturates
as it does in a camera exposed for the room, except that the renderer's shadows let 30% of a
directional light through (Newton's ``shadow_min_visibility``), so a distant light is capped at
``DISTANT_CAP`` to keep shadowed interiors from washing out. A local light's renderer colour is scaled by
``(1 + 0.02 d^2)`` at the reference distance so that its falloff matches 1/d^2 there. Colour
temperature (when enabled) tints the colour (Planckian locus approximation). The renderer's
lights are private arrays of its render context in Newton 1.8 (only one default light is public);
this module writes them and falls back to the default light when a scene has none. When Newton
imports USD lights itself this mapping should be dropped.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger(__name__)

REFERENCE_DISTANCE = 2.0  # [m] where local lights' falloff is matched to 1/d^2
DISTANT_CAP = 0.8  # renderer value cap of a distant light (its shadows still pass 30% of it)
SPOT, DIRECTIONAL, POINT = 0, 1, 2


def kelvin_to_rgb(kelvin: float) -> np.ndarray:
    """Linear-ish RGB tint (max component 1) of a black body at ``kelvin`` [K] (1000-40000),
    Tanner Helland's fit of the Planckian locus."""
    t = float(np.clip(kelvin, 1000.0, 40000.0)) / 100.0
    r = 255.0 if t <= 66 else 329.698727446 * (t - 60) ** -0.1332047592
    g = 99.4708025861 * np.log(t) - 161.1195681661 if t <= 66 else 288.1221695283 * (t - 60) ** -0.0755148492
    b = 255.0 if t >= 66 else (0.0 if t <= 19 else 138.5177312231 * np.log(t - 10) - 305.0447927307)
    rgb = np.clip(np.array([r, g, b]) / 255.0, 0.0, 1.0) ** 2.2  # sRGB-ish -> linear
    return rgb / rgb.max()


@dataclass(frozen=True, kw_only=True)
class UsdLight:
    """A UsdLux light in world coordinates: kind (the USD type name), position [m] (3,),
    direction (3,) (the light's -Z axis, where it shines), color linear RGB (tinted by the colour
    temperature when enabled), intensity, exposure, area [m^2] of the emitter's projected area
    (pi r^2 for spheres, w h for rects; 1 for distant and dome lights), cone_angle [deg]
    (ShapingAPI, or None), path, normalize_area [m^2]: the surface area its luminance is divided
    by when ``inputs:normalize`` is on (None: off, or a distant or dome light)."""

    kind: str
    path: str
    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    color: tuple[float, float, float]
    intensity: float
    exposure: float
    area: float
    cone_angle: float | None = None
    normalize_area: float | None = None

    @property
    def is_local(self) -> bool:
        return self.kind not in ("DistantLight", "DomeLight")

    @property
    def illuminance(self) -> float:
        """E [lux]: on a surface facing a distant light; from a dome on a horizontal surface; from
        a local light at REFERENCE_DISTANCE (I / d^2 with I = L * area [cd])."""
        scale = self.intensity * 2.0**self.exposure
        if self.normalize_area:
            scale /= self.normalize_area
        if self.kind == "DistantLight":
            return scale
        if self.kind == "DomeLight":
            return float(np.pi * scale)
        return scale * self.area / REFERENCE_DISTANCE**2


def read_usd_lights(stage) -> tuple[UsdLight, ...]:
    """Every UsdLux light of the stage (world transforms, Z up)."""
    from pxr import Usd, UsdGeom, UsdLux

    lights = []
    cache = UsdGeom.XformCache(Usd.TimeCode.Default())
    for prim in stage.Traverse():
        if not prim.HasAPI(UsdLux.LightAPI):
            continue
        api = UsdLux.LightAPI(prim)
        m = np.array(cache.GetLocalToWorldTransform(prim), float).T  # USD row-vector -> column
        pos = m[:3, 3]
        d = -m[:3, 2]
        d = d / (np.linalg.norm(d) or 1.0)
        kind = prim.GetTypeName()
        area = surface = 1.0
        if kind == "SphereLight":
            r = UsdLux.SphereLight(prim).GetRadiusAttr().Get() or 0.5
            area, surface = np.pi * r * r, 4 * np.pi * r * r
        elif kind == "RectLight":
            lt = UsdLux.RectLight(prim)
            area = surface = (lt.GetWidthAttr().Get() or 1.0) * (lt.GetHeightAttr().Get() or 1.0)
        elif kind == "DiskLight":
            r = UsdLux.DiskLight(prim).GetRadiusAttr().Get() or 0.5
            area = surface = np.pi * r * r
        elif kind == "CylinderLight":
            lt = UsdLux.CylinderLight(prim)
            r = lt.GetRadiusAttr().Get() or 0.5
            area, surface = np.pi * r * r, 2 * np.pi * r * (lt.GetLengthAttr().Get() or 1.0)
        normalize = bool(api.GetNormalizeAttr().Get()) and kind not in ("DistantLight", "DomeLight")
        cone = None
        if prim.HasAPI(UsdLux.ShapingAPI):
            cone = UsdLux.ShapingAPI(prim).GetShapingConeAngleAttr().Get()
        color = np.asarray(api.GetColorAttr().Get() or (1.0, 1.0, 1.0), float)
        if api.GetEnableColorTemperatureAttr().Get():
            color = color * kelvin_to_rgb(api.GetColorTemperatureAttr().Get() or 6500.0)
        lights.append(
            UsdLight(
                kind=kind,
                path=str(prim.GetPath()),
                position=tuple(map(float, pos)),
                direction=tuple(map(float, d)),
                color=tuple(map(float, color)),
                intensity=float(api.GetIntensityAttr().Get() or 1.0),
                exposure=float(api.GetExposureAttr().Get() or 0.0),
                area=float(area),
                cone_angle=None if cone is None else float(cone),
                normalize_area=float(surface) if normalize else None,
            )
        )
    return tuple(lights)


@dataclass(frozen=True)
class RendererLight:
    """A light as the renderer takes it: type (SPOT, DIRECTIONAL, POINT), position, direction,
    color (radiance), shadows."""

    type: int
    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    color: tuple[float, float, float]
    cast_shadow: bool
    source: str


def auto_exposure_lux(lights: Sequence[UsdLight]) -> float:
    """The illuminance [lux] shown as renderer value 1 (see the module doc)."""
    indoor = sum(lt.illuminance for lt in lights if lt.kind != "DistantLight")
    if indoor > 0:
        return indoor
    return sum(lt.illuminance for lt in lights) or 1.0


def map_lights(
    lights: Sequence[UsdLight], exposure_lux: float | None = None
) -> tuple[list[RendererLight], np.ndarray | None]:
    """The renderer lights and the ambient sky colour (from dome lights, or None)."""
    e_ref = exposure_lux or auto_exposure_lux(lights)
    out: list[RendererLight] = []
    sky = None
    for lt in lights:
        value = lt.illuminance / e_ref
        if lt.kind == "DistantLight":
            value = min(value, DISTANT_CAP)
        if lt.is_local:
            value *= 1.0 + 0.02 * REFERENCE_DISTANCE**2
        c = tuple(float(x) for x in np.asarray(lt.color) * value)
        if lt.kind == "DomeLight":
            sky = np.asarray(c) if sky is None else sky + c
            continue
        if lt.kind == "DistantLight":
            t, shadow = DIRECTIONAL, True
        elif lt.kind in ("RectLight", "DiskLight"):
            t, shadow = SPOT, False
        elif lt.kind == "SphereLight" and lt.cone_angle is not None and lt.cone_angle < 90.0:
            t, shadow = SPOT, False
        else:
            t, shadow = POINT, False
        out.append(RendererLight(t, lt.position, lt.direction, c, shadow, lt.path))
    return out, sky


def apply_lights(
    camera, lights: Sequence[UsdLight], exposure_lux: float | None = None
) -> list[RendererLight]:
    """Install the scene lights in a SensorCamera (see the module doc); returns what was used."""
    import warp as wp

    mapped, sky = map_lights(lights, exposure_lux)
    if not mapped:
        camera.create_default_light(enable_shadows=True)
        log.info("scene has no UsdLux lights: using the renderer's default directional light")
    else:
        rc = camera._render_context  # Newton 1.8 keeps scene lights private (see module doc)
        dev = rc.device
        rc._lights_active = wp.array([True] * len(mapped), dtype=wp.bool, device=dev)
        rc._lights_type = wp.array([m.type for m in mapped], dtype=wp.int32, device=dev)
        rc._lights_cast_shadow = wp.array([m.cast_shadow for m in mapped], dtype=wp.bool, device=dev)
        rc._lights_position = wp.array([wp.vec3f(*m.position) for m in mapped], dtype=wp.vec3f, device=dev)
        rc._lights_orientation = wp.array(
            [wp.vec3f(*m.direction) for m in mapped], dtype=wp.vec3f, device=dev
        )
        rc._lights_color = wp.array([wp.vec3f(*m.color) for m in mapped], dtype=wp.vec3f, device=dev)
    if sky is not None:
        camera.set_ambient_light(tuple(sky), tuple(0.3 * sky))
    return mapped


# --------------------------------------------------------------------------------------------
# Cameras
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class CameraSpec:
    """A camera. link: robot link it rides on (its frame is the optical frame), or None for a
    fixed camera at ``pose`` (camera-to-world 4x4, optical frame). width, height [px];
    vertical_fov [rad]."""

    name: str
    width: int = 128
    height: int = 128
    vertical_fov: float = 1.0
    link: str | None = None
    pose: tuple[tuple[float, ...], ...] | None = None

    @property
    def intrinsics(self) -> Intrinsics:
        fy = 0.5 * self.height / np.tan(0.5 * self.vertical_fov)
        return Intrinsics(
            width=self.width,
            height=self.height,
            fx=fy,
            fy=fy,
            cx=self.width / 2.0,
            cy=self.height / 2.0,
            vertical_fov=self.vertical_fov,
        )


@dataclass(frozen=True, kw_only=True)
class Intrinsics:
    """Pinhole intrinsics [px]: fx, fy focal lengths, (cx, cy) principal point (pixel-edge
    origin: pixel (u, v) centre is at (u + 0.5, v + 0.5)); vertical_fov [rad]."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    vertical_fov: float

    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[tuple[float, ...], ...]:
    """Camera-to-world 4x4 of a camera at ``eye`` looking at ``target`` (optical frame, -Z forward)."""
    from stages.simulate.robot import look_rotation

    m = np.eye(4)
    m[:3, :3] = look_rotation(np.asarray(target, float) - np.asarray(eye, float), np.asarray(up, float))
    m[:3, 3] = eye
    return tuple(tuple(float(v) for v in row) for row in m)


def robot_cameras(desc) -> list[CameraSpec]:
    """The head and wrist cameras of a robot description."""
    return [
        CameraSpec(name=n, width=c.width, height=c.height, vertical_fov=c.vertical_fov, link=c.link)
        for n, c in desc.cameras.items()
    ]


@dataclass(frozen=True, kw_only=True)
class CameraFrame:
    """One camera's images over the rendered worlds. rgb (V, H, W, 3) uint8 sRGB; depth (V, H, W)
    float32 planar depth [m] (0: no hit); shape (V, H, W) int32 shape index (-1: no hit);
    extrinsics (V, 4, 4) camera-to-world (optical frame -Z forward, +Y up); worlds (V,)."""

    name: str
    intrinsics: Intrinsics
    rgb: np.ndarray | None
    depth: np.ndarray | None
    shape: np.ndarray | None
    extrinsics: np.ndarray
    worlds: np.ndarray

    def labels(self, shape_label: np.ndarray) -> np.ndarray:
        """Semantic label per pixel (V, H, W) (str; '' where nothing was hit)."""
        lab = np.concatenate([np.asarray(shape_label, dtype=object), np.array([""], dtype=object)])
        idx = np.where(self.shape < 0, len(lab) - 1, self.shape)
        return lab[idx]

    def extrinsics_opencv(self) -> np.ndarray:
        """World-to-camera (V, 4, 4) in the OpenCV convention (+Z forward, +Y down)."""
        flip = np.diag([1.0, -1.0, -1.0, 1.0])
        return np.linalg.inv(self.extrinsics @ flip)

    def calibration(self, view: int = 0) -> CameraCalibration:
        """The intrinsics and extrinsics of one view, to record next to its images."""
        k = self.intrinsics
        return CameraCalibration(
            name=self.name, width=k.width, height=k.height, fx=k.fx, fy=k.fy, cx=k.cx, cy=k.cy,
            camera_to_world_gl=tuple(tuple(float(v) for v in row) for row in self.extrinsics[view]),
            world_to_camera_cv=tuple(tuple(float(v) for v in row) for row in self.extrinsics_opencv()[view]),
        )


@dataclass(frozen=True, kw_only=True)
class CameraCalibration:
    """A camera's recorded calibration: image size [px], pinhole intrinsics [px] (principal
    point with the pixel-edge origin), camera-to-world 4x4 in the USD/OpenGL optical convention
    (-Z forward, +Y up) and world-to-camera 4x4 in the OpenCV convention (+Z forward, +Y down)."""

    name: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    camera_to_world_gl: tuple[tuple[float, ...], ...]
    world_to_camera_cv: tuple[tuple[float, ...], ...]

    def to_json(self) -> dict:
        from dataclasses import asdict

        return asdict(self)

    def project(self, point_world) -> tuple[float, float, float]:
        """(u, v) pixel coordinates and depth [m] of a world point (OpenCV model)."""
        p = np.asarray(self.world_to_camera_cv) @ np.append(np.asarray(point_world, float), 1.0)
        return float(self.fx * p[0] / p[2] + self.cx), float(self.fy * p[1] / p[2] + self.cy), float(p[2])


@dataclass
class CameraRig:
    """Renders a set of cameras in every world of a :class:`~stages.simulate.world.Sim`.

    The third-person cameras are fixed in each world's frame (worlds share coordinates);
    exposure_lux: illuminance shown as white (None: automatic, see the module doc); shadows:
    shadow rays for distant lights (without them sunlight reaches through roofs and walls);
    textures: load and render the shapes' textures (a missing texture file raises); tile: (width,
    height) [px] of the pixel tiles rendered together (images do not depend on it); background: on
    the CPU, :meth:`render_compact_async` renders in a thread of the rig's own, beside the caller's
    physics steps (the same images, :mod:`stages.simulate.compact`)."""

    sim: object
    cameras: list[CameraSpec]
    rgb: bool = True
    depth: bool = True
    segmentation: bool = True
    exposure_lux: float | None = None
    shadows: bool = True
    textures: bool = True
    tile: tuple[int, int] = (8, 8)
    background: bool = False
    lights_used: list[RendererLight] = field(default_factory=list)

    def __post_init__(self) -> None:
        import warp as wp
        from newton.sensors import SensorCamera

        model = self.sim.model
        self._sensor = self.new_sensor()
        dev = model.device
        self._rays = {}
        self._images = {}
        nw = self.sim.world_count
        for c in self.cameras:
            self._rays[c.name] = SensorCamera.compute_camera_rays_pinhole(
                c.width, c.height, camera_fov=c.vertical_fov, device=dev
            )
            self._images[c.name] = dict(
                color=self._sensor.allocate_image_color(nw, c.width, c.height) if self.rgb else None,
                depth=self._sensor.allocate_image_depth_forward(nw, c.width, c.height)
                if self.depth
                else None,
                shape=self._sensor.allocate_image_shape_index(nw, c.width, c.height)
                if self.segmentation
                else None,
            )
        self._world_ids = wp.array(np.arange(nw, dtype=np.int32), dtype=wp.int32, device=dev)

    def new_sensor(self):
        """A Newton ``SensorCamera`` of the rig's model with its render settings and lights (the
        background render gives each camera one of its own: they render in parallel threads)."""
        from newton.sensors import SensorCamera

        # both faces: generated meshes with inward winding (ceilings seen from below) must still
        # occlude the camera and the sun
        # tiles of neighbouring pixels of one view per thread block: rays of a warp share a world
        # and a BVH path (Newton's default order puts the same pixel of every world side by side,
        # 3.6 times slower for 256 differing worlds on an H100: tests/benchmarks/bench_render.py)
        config = SensorCamera.RenderConfig(
            enable_shadows=self.shadows, enable_backface_culling=False, enable_textures=self.textures,
            render_order=SensorCamera.RenderOrder.TILED, tile_width=self.tile[0], tile_height=self.tile[1],
        )
        sensor = SensorCamera(self.sim.model, load_textures=self.textures, default_render_config=config)
        self.lights_used = apply_lights(sensor, self.sim.scene.lights, self.exposure_lux)
        return sensor

    def camera_to_world(self, cam: CameraSpec) -> np.ndarray:
        """(W, 4, 4) camera-to-world per world for the current state."""
        from scipy.spatial.transform import Rotation

        nw = self.sim.world_count
        if cam.link is None:
            return np.repeat(np.asarray(cam.pose, float)[None], nw, axis=0)
        bq = self.sim.state_0.body_q.numpy()
        idx = self.sim.robot.body[cam.link] + np.arange(nw) * self.sim.bodies_per_world
        t = bq[idx]
        m = np.tile(np.eye(4), (nw, 1, 1))
        m[:, :3, :3] = Rotation.from_quat(t[:, 3:7]).as_matrix()
        m[:, :3, 3] = t[:, :3]
        return m

    def _transforms(self, cam: CameraSpec):
        import warp as wp
        from scipy.spatial.transform import Rotation

        m = self.camera_to_world(cam)
        q = Rotation.from_matrix(m[:, :3, :3]).as_quat()
        data = np.concatenate([m[:, :3, 3], q], axis=1).astype(np.float32)
        return wp.array(data, dtype=wp.transformf, device=self.sim.model.device), m

    def render(self, *, to_numpy: bool = True) -> dict[str, CameraFrame]:
        """Render every camera in every world for ``sim.state_0``; returns frames by camera name
        (with ``to_numpy=False`` the images stay on the device and the frames hold None)."""
        model, state = self.sim.model, self.sim.state_0
        model.bvh_refit_shapes(state)
        frames = {}
        for cam in self.cameras:
            tfs, m = self._transforms(cam)
            img = self._images[cam.name]
            self._sensor.update(
                state,
                tfs,
                self._rays[cam.name],
                color_image=img["color"],
                forward_depth_image=img["depth"],
                shape_index_image=img["shape"],
                world_indices=self._world_ids,
            )
            frames[cam.name] = self._frame(cam, img, m) if to_numpy else None
        return frames

    def render_compact(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Render every camera in every world for ``sim.state_0`` and read back recording-ready
        images by camera name: RGB (W, H, Wd, 3) uint8 and depth (W, H, Wd) uint16 [mm] (rounded
        to nearest, 0 where no surface, at most 65,535: the dataset's depth encoding), converted
        on the device so that the host only copies them (needs ``rgb`` and ``depth``). On CUDA
        they are views of pinned host buffers that the next call overwrites: copy what you keep.
        :meth:`render_compact_async` returns before the GPU has rendered."""
        return self.render_compact_async().wait()

    def render_compact_async(self):
        """:meth:`render_compact` enqueued: a :class:`~stages.simulate.compact.CompactRender`
        whose ``wait()`` returns the images."""
        from stages.simulate.compact import launch_compact

        return launch_compact(self)

    def _frame(self, cam: CameraSpec, img: dict, m: np.ndarray) -> CameraFrame:
        rgb = depth = shape = None
        if img["color"] is not None:
            packed = np.ascontiguousarray(img["color"].numpy(), dtype=np.uint32)
            # bytes 0, 1, 2 of each little-endian RGBA word are R, G, B: a view, no arithmetic
            rgb = np.ascontiguousarray(packed.view(np.uint8).reshape(*packed.shape, 4)[..., :3])
        if img["depth"] is not None:
            depth = np.asarray(img["depth"].numpy(), dtype=np.float32)
            depth[~np.isfinite(depth)] = 0.0
        if img["shape"] is not None:
            raw = img["shape"].numpy().astype(np.int64)
            shape = np.where(raw >= self.sim.model.shape_count, -1, raw).astype(np.int32)
            if depth is not None:
                shape[depth <= 0] = -1
        return CameraFrame(
            name=cam.name,
            intrinsics=cam.intrinsics,
            rgb=rgb,
            depth=depth,
            shape=shape,
            extrinsics=m,
            worlds=np.arange(self.sim.world_count),
        )


LABEL_COLORS = {
    "floor": (90, 90, 90),
    "wall": (200, 190, 160),
    "table": (150, 90, 40),
    "mug": (40, 80, 230),
    "cabinet": (230, 200, 60),
    "robot": (60, 200, 80),
    "box": (220, 60, 60),
}


def colorize_labels(labels: np.ndarray, palette: dict[str, tuple[int, int, int]] | None = None) -> np.ndarray:
    """(H, W) labels -> (H, W, 3) uint8 colours (fixed for common labels, else a stable hash
    colour; black for '')."""
    import zlib

    palette = {**LABEL_COLORS, **(palette or {})}
    out = np.zeros((*labels.shape, 3), np.uint8)
    for lab in np.unique(labels):
        if not lab:
            continue
        if lab in palette:
            col = palette[lab]
        else:
            h = zlib.crc32(str(lab).encode())
            col = (64 + h % 192, 64 + (h >> 8) % 192, 64 + (h >> 16) % 192)
        out[labels == lab] = col
    return out


def depth_to_png(depth: np.ndarray, max_depth: float | None = None) -> np.ndarray:
    """(H, W) depth [m] -> (H, W) uint8 (near bright, far dark, 0 for no hit)."""
    d = np.asarray(depth, float)
    valid = d > 0
    top = max_depth or (float(d[valid].max()) if valid.any() else 1.0)
    out = np.zeros(d.shape, np.uint8)
    out[valid] = (255 * (1.0 - np.clip(d[valid] / top, 0, 1)) * 0.85 + 38).astype(np.uint8)
    return out
