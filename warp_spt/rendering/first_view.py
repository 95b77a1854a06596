"""The first view of a scene nobody described: one rule for the command line, the viewer and the API.

A user's own model comes with no camera and, often, no light. :func:`first_view` decides, once for
every front end, what the first image shows: the scene recentred if it lies far from the origin
(in float64), which way is up (:func:`warp_spt.scene.conventions.up_axis`), whether the camera is
kept or the scene framed (:func:`should_frame`, ``Camera.frame``), warnings about a view that shows
nothing, and the studio look for a scene with no light of its own
(:func:`warp_spt.scene.conventions.studio_look`: with the studio's key light,
or the user's lights as the key); the tone map (:func:`tone_map`: the seed's curve for the seed's
own scenes, filmic for standard files) and whether to denoise when the denoiser is installed
(:func:`denoise_by_default`). ``warp-spt`` (``cli/view_checks.py``), ``warp-spt view`` and the viewer widget
(``viewer/session.py``) and :func:`quick_view` call it.

Two small Warp kernels of this module's own do the geometric queries on a ``wp.Mesh`` per OBJ:
:func:`probe` (one ray per probe pixel) and :func:`enclosing_object` (a winding number), so the
checks cost about one scene upload (``benchmarks/bench_view_checks.py``); Warp is imported on first use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from warp_spt.runtime import kernel_cache
from warp_spt.scene.camera import AXES, Camera, frame_camera, looks_z_up, stands_up
from warp_spt.scene.conventions import STUDIO_LIGHTS, UpChoice, emits_light, studio_look, up_axis
from warp_spt.scene.model import Scene
from warp_spt.scene.recentre import describe_extent, format_point, recentre
from warp_spt.scene.lights import punctual_lights
from warp_spt.scene.sky import SKY_ENVIRONMENT, Sky

# The display transform of a first image: the seed's curve for the seed's own scenes (their images
# stay the seed's, bit for bit), a filmic curve for standard files (the seed's curve turns a sunlit
# scene nearly white; images/files.tonemap_filmic keeps 6.5 stops above middle grey below white).
SEED_TONEMAP, STANDARD_TONEMAP = "seed", "filmic"


def seed_look(scene: Scene, demo: bool) -> bool:
    """True for the seed's own scenes: its demo, or a file in its dialect (:attr:`Scene.seed_dialect`)."""
    return demo or scene.seed_dialect


def tone_map(scene: Scene, demo: bool = False) -> str:
    """The first image's tone map: SEED_TONEMAP for the seed's own scenes, STANDARD_TONEMAP otherwise."""
    return SEED_TONEMAP if seed_look(scene, demo) else STANDARD_TONEMAP


def denoise_by_default(scene: Scene, demo: bool = False) -> bool:
    """Whether the first image is denoised when nobody said: a standard file (the seed's scenes keep
    the seed's images) and Open Image Denoise installed (:func:`warp_spt.rendering.denoise.available`)."""
    from warp_spt.rendering.denoise import available

    return not seed_look(scene, demo) and available()

# should_frame: the default camera is kept only if it stands outside the scene's bounds and at
# least this share of its probe pixels hit geometry, and the scene is not too close.
MIN_COVERAGE, MAX_SPAN_FOVS = 0.02, 3.0


# view_warnings: lens blur wider than this many pixels over more than this share of the hits.
BLUR_PIXELS, BLUR_SHARE = 3.0, 0.5


PROBE_SIZE = 64


def probe_shape(width: int, height: int) -> tuple[int, int]:
    """The probe image of a ``width`` x ``height`` view: the same aspect, its longer side PROBE_SIZE
    (a tall view too, whose probe would otherwise grow with its height)."""
    if height <= width:
        return PROBE_SIZE, max(1, round(PROBE_SIZE * height / width))
    return max(1, round(PROBE_SIZE * width / height)), PROBE_SIZE


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
    """The probe's kernels, built on first use so that importing this module needs no Warp."""
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

    @wp.kernel
    def probe_placed(mesh: wp.uint64, boxes: wp.uint64, inv: wp.array(dtype=wp.mat33), shift: wp.array(dtype=wp.vec3),
                     origin: wp.vec3, dirs: wp.array(dtype=wp.vec3), t_best: wp.array(dtype=float)):
        # an instanced mesh: the placements whose world boxes the ray crosses (a BVH over the boxes),
        # the ray in each one's object space, its direction unnormalised so that t stays the world distance
        i = wp.tid()
        d = dirs[i]
        best = t_best[i]
        q = wp.bvh_query_ray(boxes, origin, d)
        k = int(0)
        while wp.bvh_query_next(q, k, best):
            a = inv[k]
            h = wp.mesh_query_ray(mesh, a * (origin - shift[k]), a * d, best)
            if h.result and h.t < best:
                best = h.t
        t_best[i] = best

    return probe_mesh, inside_mesh, probe_placed


def probe(scene: Scene, camera: Camera, width: int = PROBE_SIZE, height: int | None = None,
          device: str = "cpu") -> Probe:
    """Cast one pinhole ray through each pixel centre of a small image (default 64 wide)."""
    import warp as wp

    from warp_spt.device.camera_rays import pinhole_directions  # the kernels' camera frame
    from warp_spt.runtime.warp_init import init_warp

    init_warp()              # quietly, once (the viewer and the API reach here before any upload)

    height = height or max(1, round(width))
    origin, dirs = pinhole_directions(camera, width, height)
    flat = dirs.reshape(-1, 3)
    t = np.full(len(flat), np.inf)
    if scene.meshes:
        d_dirs = wp.array(flat.astype(np.float32), dtype=wp.vec3, device=device)
        for m in scene.meshes:
            if not len(m.indices):
                continue
            mesh = wp.Mesh(points=wp.array(np.asarray(m.positions, np.float32), dtype=wp.vec3, device=device),
                           indices=wp.array(m.indices.reshape(-1), dtype=wp.int32, device=device))
            t_best = wp.full(len(flat), 1e30, dtype=float, device=device)
            o = wp.vec3(*origin.astype(np.float32).tolist())
            if m.transforms is None:
                wp.launch(_kernels()[0], dim=len(flat), device=device, inputs=[mesh.id, o, d_dirs, t_best])
            else:       # one launch for every placement: host work per placement is a few array rows
                boxes = m.placement_bounds()
                pad = 1e-5 * (np.abs(boxes).max(axis=(1, 2)) + 1e-30)[:, None]    # float32 rounding, outward
                boxes = np.stack([boxes[:, 0] - pad, boxes[:, 1] + pad], axis=1)
                bvh = wp.Bvh(wp.array(boxes[:, 0].astype(np.float32), dtype=wp.vec3, device=device),
                             wp.array(boxes[:, 1].astype(np.float32), dtype=wp.vec3, device=device))
                inv = np.linalg.inv(m.transforms[:, :3, :3])
                wp.launch(_kernels()[2], dim=len(flat), device=device,
                          inputs=[mesh.id, bvh.id, wp.array(inv.astype(np.float32), dtype=wp.mat33, device=device),
                                  wp.array(m.transforms[:, :3, 3].astype(np.float32), dtype=wp.vec3, device=device),
                                  o, d_dirs, t_best])
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
        # an instanced mesh: the point in every placement's object space at once (inside is kept by
        # any affine map); only the placements whose box holds it are asked
        if m.transforms is None:
            local = p[None]
        else:
            local = np.linalg.solve(m.transforms[:, :3, :3], (p - m.transforms[:, :3, 3])[..., None])[..., 0]
        for q in local[np.all((local >= lo) & (local <= hi), axis=1)]:
            if _winding_inside(m, q, 2.0 * float(np.linalg.norm(hi - lo)) + 1.0, device):
                return m.name
    return None


def _winding_inside(m, p: np.ndarray, max_dist: float, device: str) -> bool:
    import warp as wp

    from warp_spt.runtime.warp_init import init_warp

    init_warp()

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
    pr = pr or probe(scene, camera, *probe_shape(width, height))
    if pr.coverage == 0.0:
        out.append(_nothing_seen(scene, pr, offset))
    share = lens_blur_share(pr, camera, width)
    if share > BLUR_SHARE:
        out.append(f"the lens blur is wider than {BLUR_PIXELS:g} pixels over {100 * share:.0f}% of the "
                   f"visible geometry (aperture {camera.aperture:g}, focus {camera.focus:g}); "
                   "use --aperture 0 for a sharp image")
    return out


@dataclass(frozen=True)
class FirstView:
    """What :func:`first_view` decided: the scene to render (recentred, with the studio's ground and
    key light when the studio applies), the camera (in the recentred frame), the sky, the tone map,
    ``offset`` (world = local + offset), the up axis and why, and the lines a front end says."""

    scene: Scene
    camera: Camera
    sky: Sky | None
    tonemap: str
    offset: np.ndarray
    up: UpChoice
    studio: bool
    framed: bool
    notes: tuple[str, ...] = field(default=())
    subject: Scene | None = None     # the recentred scene without the studio's additions

    def __post_init__(self) -> None:
        if self.subject is None:
            object.__setattr__(self, "subject", self.scene)

    @property
    def warnings(self) -> list[str]:
        """The notes that are warnings (the camera sees nothing, is inside an object, ...)."""
        return [n.removeprefix("warning: ") for n in self.notes if n.startswith("warning: ")]


def first_view(scene: Scene, camera: Camera | None = None, *, width: int = 384, height: int = 288,
               up: str | None = None, studio: bool | None = None, sky: Sky | None = None,
               frame: bool = False, view: tuple[float, float] | None = None,
               look_at: Sequence[float] | None = None, frame_all: bool = False, demo: bool = False,
               keep_camera: bool | None = None, seed_camera: bool | None = None, fixed: bool | None = None,
               quiet_demo: bool = False, user_lights: bool = False, bounds: np.ndarray | None = None,
               say: Callable[[str], None] | None = None) -> FirstView:
    """The first view of ``scene`` (see the module's docs): recentre, choose the up axis, keep or
    frame the camera, warn, add the studio look.

    ``camera``: a camera to keep (as ``-cam``: never replaced by framing, Z up unless ``up``); None
    frames the scene. ``keep_camera``/``seed_camera``/``fixed`` refine that for the command line: a
    camera placed by ``--look-at`` is kept for a scene in the seed's dialect and re-framed towards its
    target otherwise; a camera path, like ``-cam``, is never re-framed (``fixed``), but unlike ``-cam``
    its up axis follows the model (``seed_camera=False``: Y up for a standard OBJ). ``sky``: a sky
    the user chose (turns the studio's sky off, and the studio itself unless ``studio=True``).
    ``frame``/``view``/``look_at``/``frame_all``: the command line's ``--frame``/``--view``/
    ``--look-at``/``--frame-all`` (a base much wider than what stands on it, such as a ground, is
    left out of the framing unless ``frame_all``). ``demo``: the built-in demo (the seed's look, no
    checks). ``user_lights``: the caller adds lights of the user's beside the scene's (the viewer's
    page); the scene's own sun, point and spot lights (``--sun``, ``--light``, a glTF file's) and an
    environment map ``sky`` count without it: with any of them the studio is lit by them, not by its
    key light. ``bounds``: (2, 3) world bounds to frame and to stand the studio under instead of the
    scene's (an animation's union over its frames, so that the camera and the ground stay put).
    ``say`` gets each line the command line prints (they are also in ``FirstView.notes``).
    Raises ValueError when the scene cannot be framed (e.g. a field of view too narrow).
    """
    notes: list[str] = []

    def note(line: str) -> None:
        notes.append(line)
        if say is not None:
            say(line)

    keep = camera is not None if keep_camera is None else keep_camera
    explicit = keep if seed_camera is None else seed_camera
    fixed = explicit if fixed is None else fixed
    scene, cam, offset = recentre(scene, camera)
    local = None if bounds is None else np.asarray(bounds, np.float64) - offset
    if offset.any():
        note(f"recentred the scene by {format_point(-offset)} for precision (far from the origin)")
    choice = choose_up(scene, up, demo=demo, cam_given=explicit)
    cam = cam.with_(up=AXES[choice.axis])
    if demo and quiet_demo:
        return FirstView(scene, cam, sky, tone_map(scene, demo), offset, choice, False, False, tuple(notes))
    pr, framed = None, False
    if not demo and not (fixed or (keep and scene.seed_dialect)):
        why = _why_frame(frame, view, scene, choice.axis)
        if not why:      # a scene in the seed's dialect: frame only if the camera would not show it
            pr = probe(scene, cam, *probe_shape(width, height))
            if should_frame(scene, cam, pr.coverage):
                why = "the default camera would not show it whole; -cam or --look-at to choose"
        if why:
            try:
                cam, side = _framed(scene, cam, choice.axis, offset, width / height, view, look_at, frame_all,
                                    local)
            except ValueError as err:
                raise ValueError(f"cannot frame the scene ({why}): {err}") from None
            note(_framed_line(why, choice, side, cam, offset))
            pr, framed = None, True
    elif fixed and not explicit and choice.reason:
        note(f"the camera path's up axis: {choice.note}")
    for warning in view_warnings(scene, cam, width, height, pr, offset):
        note(f"warning: {warning}")
    subject = scene
    env = sky is not None and sky.kind == SKY_ENVIRONMENT
    theirs = punctual_lights(scene.lights)
    look = studio_look(studio, emitting=demo or emits_light(scene), user_lights=user_lights or bool(theirs),
                       seed_dialect=scene.seed_dialect, sky_given=sky is not None, env_given=env)
    on = bool(look)
    if on:
        from warp_spt.scene.studio import add_studio, studio_sky
        if look == STUDIO_LIGHTS:
            note(_lights_line(theirs, user_lights, env, scene.bare))
        elif studio is None:
            note(f"studio look: the scene has no light of its own; a ground, a key light and a grey sky"
                 f"{'' if scene.bare else ', with its own materials'} (--no-studio to turn off)")
        scene = add_studio(scene, up=choice.axis, camera=cam, key=look != STUDIO_LIGHTS, bounds=local,
                           aspect=width / height)
        sky = sky if sky is not None else studio_sky(key=look != STUDIO_LIGHTS)
    return FirstView(scene, cam, sky, tone_map(subject, demo), offset, choice, on, framed, tuple(notes), subject)


def _lights_line(lights, page: bool, env: bool, bare: bool) -> str:
    """The one line of the studio lit by the user's lights (conventions.STUDIO_LIGHTS)."""
    kinds = [type(light).__name__.removesuffix("Light").lower() for light in lights]
    named = [f"{n} {k} lights" if n > 1 else f"a {k} light" for k in ("sun", "point", "spot")
             for n in [kinds.count(k)] if n]
    named += ["the page's lights"] if page else []
    named += ["the environment map"] if env else []
    key = " and ".join(named) if len(named) < 3 else ", ".join(named[:-1]) + " and " + named[-1]
    fill = "" if env else " and a dim grey fill sky"
    return (f"studio look with your lights: no light of its own; a ground{fill} under {key} as the key, "
            f"no studio key light{'' if bare else ', with its own materials'} (--no-studio to turn off)")


def choose_up(scene: Scene, up: str | None = None, *, demo: bool = False, cam_given: bool = False) -> UpChoice:
    """:func:`warp_spt.scene.conventions.up_axis` for ``scene``, its geometric cues computed only
    where the rule reads them (none for glTF and USD files, whose axis their format fixes)."""
    formats = tuple(getattr(scene, "formats", ()))
    decided = up or demo or scene.seed_dialect or cam_given or (formats and set(formats) <= {"glTF", "USD"})
    hint = getattr(scene, "up_hint", None)
    hinted = "PLY" in formats and hint is not None         # a PLY header that states it: no shape read
    z_scan = not (decided or hinted) and looks_z_up(scene)
    stands = None if decided or hinted or z_scan else stands_up(scene, strict="PLY" not in formats)
    return up_axis(up, demo=demo, seed_dialect=scene.seed_dialect, cam_given=cam_given, z_scan=z_scan,
                   formats=formats, hint=hint, stands=stands)


def _why_frame(frame: bool, view, scene: Scene, up: str) -> str:
    """Why the scene is framed whatever the camera sees, or "" (see the help's rule)."""
    if frame:
        return "--frame"
    if view is not None:
        return "--view"
    if not scene.seed_dialect:
        return "your own model; the seed's default camera is made for the seed's scenes"
    if up != "z":
        return f"--up {up}: the seed's default camera is a Z-up one"
    return ""


def _framed(scene: Scene, camera: Camera, up: str, offset, aspect: float, view, look_at,
            frame_all: bool = False, bounds: np.ndarray | None = None) -> tuple[Camera, str]:
    """The framing camera and the words for its side: --view's angles, or a three-quarter view
    from the front (face-on for a flat cut-out), looking at --look-at's point or the centre; the
    objects on a wide base rather than the base (unless ``frame_all``)."""
    from warp_spt.scene.camera import AZIMUTH, ELEVATION, flat_normal, orbit_vector, subject_bounds

    target = None if look_at is None else np.asarray(look_at, dtype=np.float64) - offset
    az, el = view if view is not None else (AZIMUTH, ELEVATION)
    towards, side = None, (f"from azimuth {az:g}, elevation {el:g}" if view is not None
                           else "a three-quarter view from the front (--view to choose)")
    if view is None and target is None:
        towards = flat_normal(scene, orbit_vector(up, AZIMUTH, ELEVATION))
        if towards is not None:
            side = "face-on: a flat model (--view to choose)"
    subject = bounds if bounds is not None or frame_all else subject_bounds(scene, up)
    if bounds is not None:
        side += "; over every frame's bounds, once"
    elif subject is not None:
        side += "; the objects on the base, not the whole base (--frame-all to include it)"
    # placed as the default lens frames it, then given the camera's own fov: a --fov zooms in or out
    # from the framed view (framing at that fov would move the camera back and keep the same picture)
    framed = frame_camera(scene if subject is None else subject, up=up, aspect=aspect, template=camera,
                          fov=Camera().fov, azimuth=az, elevation=el, target=target, towards=towards)
    return framed.with_(fov=camera.fov,
                        aperture=0.0 if camera.aperture == Camera().aperture else camera.aperture), side


def _framed_line(why: str, up: UpChoice, side: str, camera: Camera, offset) -> str:
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


def sees_nothing(scene: Scene, camera: Camera, width: int, height: int) -> str | None:
    """The "camera sees no geometry" warning of a render of a host scene (recentred first, as the
    render does), or None."""
    local, cam, offset = recentre(scene, camera)
    pr = probe(local, cam, *probe_shape(width, height))
    return None if pr.coverage else _nothing_seen(local, pr, offset)


def _nothing_seen(scene: Scene, pr: "Probe", offset) -> str:
    b = scene.bounds + np.asarray(offset, dtype=np.float64)
    return (f"the camera sees no geometry (a {pr.t.shape[1]}x{pr.t.shape[0]} probe hit nothing; the scene "
            f"spans {format_point(b[0])}..{format_point(b[1])}, {describe_extent(scene)}); "
            "use --frame or aim the camera at it")
