"""The command line's look at a scene before rendering: recentring, framing, probes, warnings, studio.

Everything here works on the numpy :class:`Scene` and a :class:`Camera`, before the engine sees
them. Two small Warp kernels of this module's own do the geometric queries on a ``wp.Mesh`` per
OBJ: :func:`probe` (one ray per probe pixel) and :func:`enclosing_object` (a winding number), so the
checks cost about one scene upload (``benchmarks/bench_view_checks.py``); Warp is imported on first use.

* :func:`should_frame`: the CLI's rule for telling a user's model from the seed's setups.
* :func:`view_warnings`: camera inside a closed mesh, camera sees no geometry, lens blur too large.
* :func:`prepare_view`: all of the above for one command (with the up axis and studio rules of
  :mod:`warp_spt.scene.conventions`), then the upload.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Sequence

import numpy as np

from warp_spt.cli.common import CompileNotice, RunError
from warp_spt.runtime import kernel_cache
from warp_spt.scene.camera import Camera, frame_camera
from warp_spt.scene.model import Scene
from warp_spt.scene.recentre import format_point, recentre
from warp_spt.scene.sky import Sky

if TYPE_CHECKING:
    from warp_spt.scene.camera import Camera


# should_frame: the default camera is kept only if it stands outside the scene's bounds and at
# least this share of its probe pixels hit geometry, and the scene is not too close.
MIN_COVERAGE, MAX_SPAN_FOVS = 0.02, 3.0


# view_warnings: lens blur wider than this many pixels over more than this share of the hits.
BLUR_PIXELS, BLUR_SHARE = 3.0, 0.5


PROBE_SIZE = 64


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


@kernel_cache.memoize("view checks")
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

    from warp_spt.core.camera_rays import pinhole_directions  # the kernels' camera frame

    height = height or max(1, round(width))
    origin, dirs = pinhole_directions(camera, width, height)
    flat = dirs.reshape(-1, 3)
    t = np.full(len(flat), np.inf)
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


def prepare_view(opts, scene, say, notice: "CompileNotice | None" = None) -> tuple[object, Camera, Sky]:
    """The scene (uploaded to the device), camera and sky to render.

    The scene is recentred if far from the origin, framed when the rule says so (see
    :func:`warp_spt.cli.view_checks.should_frame`), checked for views that show nothing, and given the studio
    preset if asked. The probe's kernel may compile on a first run: ``notice`` announces it.
    """
    from warp_spt.core.device_scene import DeviceScene

    with notice or CompileNotice(say):
        scene, camera, sky = _view(opts, scene, say)
    return DeviceScene(scene), camera, sky


def frame_view(opts, say):
    """The view of each frame of an animation: :func:`_view`, the very preparation of a single image,
    with the frame's camera; a camera path, like -cam, is never replaced by framing and keeps the
    seed's Z up unless --up says otherwise. A message that every frame repeats is said once."""
    fixed = opts.cam_given or bool(opts.camera_path)
    explicit = opts.cam_explicit or bool(opts.camera_path)
    said: set[str] = set()

    def say_once(msg: str) -> None:
        if msg not in said:
            said.add(msg)
            say(msg)

    def view(scene, camera):
        return _view(replace(opts, camera=camera, cam_given=fixed, cam_explicit=explicit), scene, say_once)
    return view


def _view(opts, scene, say) -> tuple[object, Camera, Sky]:
    """Recentre, choose the up axis, place the camera (keep, or frame), warn, add the studio look."""
    from warp_spt.scene.camera import AXES
    from warp_spt.scene.conventions import up_axis, wants_studio

    file_camera = None
    if getattr(opts, "file_camera", None) is not None:       # --camera: the files' camera, never framed
        file_camera = _file_camera(opts, scene)
        opts = replace(opts, camera=file_camera, cam_given=True, cam_explicit=False, frame=False, view=None)
    scene, camera, offset = recentre(scene, opts.camera)
    if offset.any():
        say(f"recentred the scene by {format_point(-offset)} for precision (far from the origin)")
    up = up_axis(opts.up, demo=opts.uses_demo_scene, seed_dialect=scene.seed_dialect, cam_given=opts.cam_explicit)
    camera = camera.with_(up=AXES[up.axis] if file_camera is None or opts.up else file_camera.up)
    if opts.uses_demo_scene and opts.quiet:
        return scene, camera, opts.sky
    pr = None
    if not opts.uses_demo_scene and file_camera is None and not (
            opts.cam_explicit or (opts.cam_given and scene.seed_dialect)):
        why = _why_frame(opts, scene, up.axis)
        if not why:      # a scene in the seed's dialect: frame only if the camera would not show it
            pr = probe(scene, camera, PROBE_SIZE, max(1, round(PROBE_SIZE * opts.height / opts.width)))
            if should_frame(scene, camera, pr.coverage):
                why = "the default camera would not show it whole; -cam or --look-at to choose"
        if why:
            camera, side = _framed(opts, scene, camera, up.axis, offset, why)
            say(_framed_line(why, up, side, camera, offset))
            pr = None
    for warning in view_warnings(scene, camera, opts.width, opts.height, pr, offset):
        say(f"warning: {warning}")
    sky = opts.sky
    if wants_studio(opts.studio, bare=scene.bare and not opts.uses_demo_scene, sky_given=opts.sky_given):
        from warp_spt.scene.studio import add_studio, studio_sky
        if opts.studio is None:
            say("studio look for a bare model: clay, a ground, a key light, a grey sky (--no-studio to turn off)")
        scene = add_studio(scene, up=up.axis, camera=camera)
        sky = opts.sky if opts.sky_given else studio_sky()
    return scene, camera, sky


def _file_camera(opts, scene) -> Camera:
    """The camera --camera names, for this image's aspect (the file's vertical field of view)."""
    from warp_spt.io.gltf import choose_camera

    try:
        return choose_camera(scene.cameras, opts.file_camera, opts.width, opts.height)
    except ValueError as err:
        raise RunError(f"--camera {opts.file_camera}: {err}") from None


def _why_frame(opts, scene, up: str) -> str:
    """Why the scene is framed whatever the camera sees, or "" (see the help's rule)."""
    if opts.frame:
        return "--frame"
    if opts.view is not None:
        return "--view"
    if not scene.seed_dialect:
        return "your own model; the seed's default camera is made for the seed's scenes"
    if up != "z":
        return f"--up {up}: the seed's default camera is a Z-up one"
    return ""


def _framed(opts, scene, camera: Camera, up: str, offset, why: str) -> tuple[Camera, str]:
    """The framing camera and the words for its side: --view's angles, or a three-quarter view
    from the front (face-on for a flat cut-out), looking at --look-at's point or the centre."""
    from warp_spt.scene.camera import AZIMUTH, ELEVATION, flat_normal, orbit_vector

    target = None if opts.look_at is None else np.asarray(opts.look_at, dtype=np.float64) - offset
    az, el = opts.view if opts.view is not None else (AZIMUTH, ELEVATION)
    towards, side = None, (f"from azimuth {az:g}, elevation {el:g}" if opts.view is not None
                           else "a three-quarter view from the front (--view to choose)")
    if opts.view is None and target is None:
        towards = flat_normal(scene, orbit_vector(up, AZIMUTH, ELEVATION))
        if towards is not None:
            side = "face-on: a flat model (--view to choose)"
    try:     # with_ validates: a --fov so narrow that the camera would stand too far is refused here
        framed = frame_camera(scene, up=up, aspect=opts.width / opts.height, template=camera, azimuth=az,
                              elevation=el, target=target, towards=towards)
        return framed.with_(aperture=0.0 if camera.aperture == Camera().aperture else camera.aperture), side
    except ValueError as err:
        raise RunError(f"cannot frame the scene ({why}): {err}; a wider --fov stands closer") from None


def _framed_line(why: str, up, side: str, camera: Camera, offset) -> str:
    """The one line that says how the scene was framed, what was assumed, and the -cam that
    reproduces it (with --up when the axis is not the one -cam implies)."""
    assumed = f"{up.note}, " if up.note else ""
    again = " ".join(_short(v) for v in _cam_numbers(camera, offset))
    axis = "" if up.axis == "z" else (f" --up={up.axis}" if up.axis.startswith("-") else f" --up {up.axis}")
    return f"framed the scene ({why}): {assumed}{side}; -cam {again}{axis}"


def _cam_numbers(cam: Camera, offset) -> list[float]:
    """A camera as -cam's nine numbers in world coordinates."""
    return [*(p + o for p, o in zip(cam.position, offset)), *cam.direction, cam.fov, cam.focus, cam.aperture]


def _short(v: float) -> str:
    """A -cam number that reads back as the very same float64 (so the printed -cam reproduces the
    image bit for bit), without a trailing ".0"; -0 written as 0."""
    text = repr(float(v)).removesuffix(".0")
    return "0" if text == "-0" else text
