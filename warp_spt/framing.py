"""Host-side view checks for users' own models: framing, probes, warnings and recentring.

Everything here works on the numpy :class:`Scene` and a :class:`Camera`, before the engine sees
them. Two small Warp kernels of this module's own do the geometric queries on a ``wp.Mesh`` per
OBJ: :func:`probe` (one ray per probe pixel) and :func:`enclosing_object` (a winding number), so the
checks cost about one scene upload (``benchmarks/bench_view_checks.py``).

* :func:`frame_camera` (also ``Camera.frame(scene, up=...)``): a three-quarter view from the front,
  the whole bounding box in view with a margin, focused at its centre, pinhole lens.
* :func:`should_frame`: the CLI's rule for telling a user's model from the seed's setups.
* :func:`view_warnings`: camera inside a closed mesh, camera sees no geometry, lens blur too large.
* :func:`recentre` / :func:`render`: far-from-origin scenes are shifted to the origin in float64
  before anything reaches the float32 engine.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from .camera import Camera, up_vector
from .scene import Scene

# Framing: azimuth from the front towards the side, elevation above the horizon, in degrees; the
# box's projection fills 1/MARGIN of the frame's half-width or half-height.
AZIMUTH, ELEVATION, MARGIN = 35.0, 25.0, 1.05
# should_frame: the default camera is kept only if it stands outside the scene's bounds and at
# least this share of its probe pixels hit geometry, and the scene is not too close.
MIN_COVERAGE, MAX_SPAN_FOVS = 0.02, 3.0
# view_warnings: lens blur wider than this many pixels over more than this share of the hits.
BLUR_PIXELS, BLUR_SHARE = 3.0, 0.5
# recentre: scenes whose centre lies farther from the origin than this many times their size.
RECENTRE_RATIO = 4.0
PROBE_SIZE = 64


# ---------------------------------------------------------------------------------------------
# Framing


def front_vector(up: np.ndarray) -> np.ndarray:
    """The direction from a model towards its viewer for an up axis: -Y for Z up (the seed's camera
    stands at -Y), +Z for Y up (the glTF/OpenGL convention: models face +Z), +Z for X up."""
    for cand in ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)):
        f = np.asarray(cand) - np.dot(cand, up) * up
        if np.linalg.norm(f) > 0.5:
            return f / np.linalg.norm(f)
    return np.array([1.0, 0.0, 0.0])


def _box(scene_or_bounds: Scene | np.ndarray) -> np.ndarray:
    b = scene_or_bounds.bounds if isinstance(scene_or_bounds, Scene) else np.asarray(scene_or_bounds, np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)):
        raise ValueError("framing needs a scene with geometry (finite bounds)")
    return b


def frame_camera(scene: Scene | np.ndarray, up: str | Sequence[float] | None = None, *, fov: float | None = None,
                 aspect: float = 1.0, margin: float = MARGIN, template: Camera | None = None) -> Camera:
    """A camera that shows all of ``scene`` (or (2, 3) bounds) from the front, three-quarter view.

    ``aspect`` is width / height of the image. ``fov`` defaults to the template's (the seed's 38°);
    ``up`` to the template's up axis (Z). The result is a pinhole focused at the bounds' centre.
    """
    b = _box(scene)
    base = template or Camera()
    u = up_vector(up if up is not None else base.up)
    fov = float(fov if fov is not None else base.fov)
    front = front_vector(u)
    side = np.cross(u, front)
    az, el = math.radians(AZIMUTH), math.radians(ELEVATION)
    towards_camera = math.cos(el) * (math.cos(az) * front + math.sin(az) * side) + math.sin(el) * u
    centre = 0.5 * (b[0] + b[1])
    probe_cam = Camera(position=tuple(centre), direction=tuple(-towards_camera), fov=fov, focus=1.0,
                       aperture=0.0, up=tuple(u))
    d, right, img_up = probe_cam.axes()
    corners = np.array([[b[i][0], b[j][1], b[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]) - centre
    tx = math.tan(math.radians(fov) / 2.0) / margin
    ty = tx / aspect
    x, y, z = corners @ right, corners @ img_up, corners @ d
    dist = float(max(np.max(np.abs(x) / tx - z), np.max(np.abs(y) / ty - z)))
    size = float(np.linalg.norm(b[1] - b[0]))
    dist = max(dist, float(np.max(-z)) + 1e-3 * size, 1e-6 * max(size, float(np.max(np.abs(centre)))), 1e-12)
    return Camera(position=tuple(float(v) for v in centre - d * dist), direction=tuple(float(v) for v in d),
                  fov=fov, aperture=0.0, focus=dist, up=tuple(float(v) for v in u))


def should_frame(scene: Scene, camera: Camera, coverage: float) -> bool:
    """The CLI's rule when a user gives ``-obj`` without ``-cam``: frame the scene automatically when
    the (default) camera stands inside the scene's bounding box, sees almost none of it (``coverage``
    below MIN_COVERAGE), or is so close that the scene's bounding sphere spans more than
    MAX_SPAN_FOVS fields of view. The seed's demo scenes are seen from outside, fill the frame and
    span 1.5 fields of view, so they keep the seed's camera."""
    b = scene.bounds
    p = np.asarray(camera.position, dtype=np.float64)
    inside = bool(np.all(p >= b[0]) and np.all(p <= b[1]))
    radius = 0.5 * float(np.linalg.norm(b[1] - b[0]))
    dist = float(np.linalg.norm(0.5 * (b[0] + b[1]) - p))
    span = 180.0 if radius >= dist else 2.0 * math.degrees(math.asin(radius / dist))
    return inside or coverage < MIN_COVERAGE or span > MAX_SPAN_FOVS * camera.fov


# ---------------------------------------------------------------------------------------------
# The probe: a low-resolution pinhole look through the camera


@dataclass
class Probe:
    """Per probe pixel: distance along the primary ray to the first hit (inf for a miss)."""

    t: np.ndarray           # (h, w) float64
    directions: np.ndarray  # (h, w, 3) float64 unit ray directions

    @property
    def hits(self) -> np.ndarray:
        return np.isfinite(self.t)

    @property
    def coverage(self) -> float:
        """Share of probe pixels that see geometry."""
        return float(self.hits.mean())


@functools.cache
def _kernels():
    """The probe's two kernels, built on first use so that importing this module needs no Warp."""
    import warp as wp

    @wp.kernel
    def probe_mesh(mesh: wp.uint64, origin: wp.vec3, dirs: wp.array(dtype=wp.vec3),
                   t_best: wp.array(dtype=float)):
        i = wp.tid()
        q = wp.mesh_query_ray(mesh, origin, dirs[i], t_best[i])
        if q.result:
            t_best[i] = q.t

    @wp.kernel
    def inside_mesh(mesh: wp.uint64, point: wp.vec3, max_dist: float, threshold: float,
                    inside: wp.array(dtype=wp.int32)):
        q = wp.mesh_query_point_sign_winding_number(mesh, point, max_dist, 2.0, threshold)
        if q.result and q.sign < 0.0:
            inside[0] = 1

    return probe_mesh, inside_mesh


def probe(scene: Scene, camera: Camera, width: int = PROBE_SIZE, height: int | None = None,
          device: str = "cpu") -> Probe:
    """Cast one pinhole ray through each pixel centre of a small image (default 64 wide)."""
    import warp as wp

    height = height or max(1, round(width))
    plane = camera.image_plane(width, height)
    xs, ys = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    target = plane["upper_left"] + xs[..., None] * plane["x_step"] - ys[..., None] * plane["y_step"]
    dirs = target - plane["origin"]
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    flat = dirs.reshape(-1, 3)
    t = np.full(len(flat), np.inf)
    origin = plane["origin"]
    if scene.meshes:
        d_dirs = wp.array(flat.astype(np.float32), dtype=wp.vec3, device=device)
        for m in scene.meshes:
            if not len(m.indices):
                continue
            mesh = wp.Mesh(points=wp.array(m.positions, dtype=wp.vec3, device=device),
                           indices=wp.array(m.indices.reshape(-1), dtype=wp.int32, device=device))
            t_best = wp.full(len(flat), 1e30, dtype=float, device=device)
            wp.launch(_kernels()[0], dim=len(flat), device=device,
                      inputs=[mesh.id, wp.vec3(*origin.astype(np.float32).tolist()), d_dirs, t_best])
            tm = t_best.numpy().astype(np.float64)
            t = np.minimum(t, np.where(tm < 1e29, tm, np.inf))
    for c, r in zip(scene.spheres[:, :3].astype(np.float64), scene.spheres[:, 3].astype(np.float64)):
        t = np.minimum(t, _sphere_hits(origin, flat, c, r))
    return Probe(t.reshape(height, width), dirs)


def _sphere_hits(o: np.ndarray, dirs: np.ndarray, c: np.ndarray, r: float) -> np.ndarray:
    """Nearest positive hit distance of unit rays from ``o`` with a sphere (inf for a miss)."""
    oc = o - c
    b = dirs @ oc
    perp = oc - b[:, None] * dirs
    disc = r * r - np.einsum("ij,ij->i", perp, perp)
    root = np.sqrt(np.maximum(disc, 0.0))
    t0, t1 = -b - root, -b + root
    t = np.where(t0 > 0, t0, t1)
    return np.where((disc >= 0) & (t > 0), t, np.inf)


# ---------------------------------------------------------------------------------------------
# Warnings


INSIDE_WINDING = 0.75   # a closed surface gives 1 inside, an open sheet at most 0.5 on either side


def enclosing_object(scene: Scene, point: Sequence[float], device: str = "cpu") -> str | None:
    """The name of a mesh (or "a sphere") that ``point`` lies inside, or None.

    Inside a mesh means a generalized winding number above INSIDE_WINDING (Warp's BVH-accelerated
    query): inside a closed or nearly closed surface whose faces point outward, as a scanned solid's
    do. A room modelled with its faces pointing inward, seen from inside, gives -1 and is not
    reported, nor is an open sheet.
    """
    p = np.asarray(point, dtype=np.float64)
    for c, r in zip(scene.spheres[:, :3].astype(np.float64), scene.spheres[:, 3].astype(np.float64)):
        if np.linalg.norm(p - c) < r:
            return "a sphere"
    for m in scene.meshes:
        if not len(m.indices):
            continue
        lo, hi = m.positions.min(0).astype(np.float64), m.positions.max(0).astype(np.float64)
        if np.any(p < lo) or np.any(p > hi):
            continue
        if _winding_inside(m, p, 2.0 * float(np.linalg.norm(hi - lo)) + 1.0, device):
            return m.name
    return None


def _winding_inside(m, p: np.ndarray, max_dist: float, device: str) -> bool:
    import warp as wp

    mesh = wp.Mesh(points=wp.array(m.positions, dtype=wp.vec3, device=device),
                   indices=wp.array(m.indices.reshape(-1), dtype=wp.int32, device=device),
                   support_winding_number=True)
    inside = wp.zeros(1, dtype=wp.int32, device=device)
    wp.launch(_kernels()[1], dim=1, device=device,
              inputs=[mesh.id, wp.vec3(*p.astype(np.float32).tolist()), max_dist, INSIDE_WINDING, inside])
    return bool(inside.numpy()[0])


def lens_blur_share(pr: Probe, camera: Camera, width: int, pixels: float = BLUR_PIXELS) -> float:
    """Share of probe hits whose thin-lens blur circle is wider than ``pixels`` pixels of a
    ``width``-pixel image: diameter = aperture * |focus - z| * width / (z * focus * tan(fov / 2)),
    z the hit's depth along the view axis."""
    hits = pr.hits
    if camera.aperture <= 0.0 or not hits.any():
        return 0.0
    d, _, _ = camera.axes()
    z = pr.t[hits] * (pr.directions[hits] @ d)
    blur = camera.aperture * np.abs(camera.focus - z) * width / (z * camera.focus
                                                                 * math.tan(math.radians(camera.fov) / 2))
    return float(np.mean(blur > pixels))


def view_warnings(scene: Scene, camera: Camera, width: int, height: int, pr: Probe | None = None,
                  offset: Sequence[float] = (0.0, 0.0, 0.0)) -> list[str]:
    """One-line warnings about a view that will not show the scene (empty when all is well).

    ``offset`` is what :func:`recentre` subtracted: bounds are reported in world coordinates."""
    out = []
    inside = enclosing_object(scene, camera.position)
    if inside:
        out.append(f"the camera is inside a closed object ({inside}); it will see only its inside "
                   "(use --frame, or -cam/--look-at to place it outside)")
    pr = pr or probe(scene, camera, PROBE_SIZE, max(1, round(PROBE_SIZE * height / width)))
    if pr.coverage == 0.0:
        b = scene.bounds + np.asarray(offset, dtype=np.float64)
        out.append(f"the camera sees no geometry (a {pr.t.shape[1]}x{pr.t.shape[0]} probe hit nothing; "
                   f"the scene spans {format_point(b[0])}..{format_point(b[1])}); use --frame or aim the camera at it")
    share = lens_blur_share(pr, camera, width)
    if share > BLUR_SHARE:
        out.append(f"the lens blur is wider than {BLUR_PIXELS:g} pixels over {100 * share:.0f}% of the "
                   f"visible geometry (aperture {camera.aperture:g}, focus {camera.focus:g}); "
                   "use --aperture 0 for a sharp image")
    return out


def format_point(v: Sequence[float]) -> str:
    """A point as (x, y, z) with 6 significant digits."""
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def describe_bounds(scene: Scene) -> str:
    """The scene's bounds for the CLI's 'loaded' line."""
    b = scene.bounds
    return f"bounds {format_point(b[0])}..{format_point(b[1])}"


# ---------------------------------------------------------------------------------------------
# Far from the origin


def recentre(scene: Scene, camera: Camera | None = None, *, ratio: float = RECENTRE_RATIO
             ) -> tuple[Scene, Camera, np.ndarray]:
    """Shift a scene far from the origin (and its camera) so that its centre is at the origin.

    Returns (scene', camera', offset) with world = local + offset. The subtraction is done in float64
    on the float32 positions, so the local coordinates are exact to float32 *relative to the scene's
    size*, not to its distance from the origin. Scenes whose centre lies within ``ratio`` times their
    size of the origin are returned unchanged (offset 0), so ordinary scenes render bit for bit as before.
    """
    camera = camera or Camera()
    b = scene.bounds
    size = float(np.max(b[1] - b[0])) if np.all(np.isfinite(b)) else 0.0
    centre = 0.5 * (b[0] + b[1])
    if not size > 0.0 or float(np.max(np.abs(centre))) <= ratio * size:
        return scene, camera, np.zeros(3)
    meshes = [replace(m, positions=(m.positions.astype(np.float64) - centre).astype(np.float32))
              for m in scene.meshes]
    spheres = scene.spheres.copy()
    if len(spheres):
        spheres[:, :3] = (scene.spheres[:, :3].astype(np.float64) - centre).astype(np.float32)
    moved = replace(scene, meshes=meshes, spheres=spheres)
    cam = replace(camera, position=tuple(float(v) for v in np.asarray(camera.position, np.float64) - centre))
    return moved, cam, centre
