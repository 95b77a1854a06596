"""The seed's camera: a position and a view direction, horizontal field of view, thin lens; Z up by default.

Besides the seed's form (position + view direction), a camera can be made from a target
(:meth:`Camera.look_at`) or fitted to a scene's bounds (:meth:`Camera.frame` with a scene, see
:mod:`warp_spt.scene.recentre`). ``up`` is the world's up axis: the seed's scenes are Z-up, most exported
models are Y-up (``up=(0, 1, 0)``).
"""


from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Iterator, Sequence

import numpy as np

from warp_spt.scene.limits import (
    MAX_CAMERA_COORDINATE,
    MAX_COORDINATE,
    MAX_IMAGE_PLANE,
    MIN_DIRECTION,
    MIN_FOCUS,
    MIN_FOV,
)
from warp_spt.scene.model import Scene

Vec3 = tuple[float, float, float]

# The seed's axes: Z up (SEMANTICS §3).
Z_UP: Vec3 = (0.0, 0.0, 1.0)
AXES: dict[str, Vec3] = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": Z_UP,
                         "-x": (-1.0, 0.0, 0.0), "-y": (0.0, -1.0, 0.0), "-z": (0.0, 0.0, -1.0)}


def up_vector(up: str | Sequence[float]) -> np.ndarray:
    """A unit float64 up vector from ``"x"``, ``"-y"``... or three numbers."""
    if isinstance(up, str):
        if up.lower() not in AXES:
            raise ValueError(f"up axis must be one of {', '.join(AXES)}, got {up!r}")
        return np.asarray(AXES[up.lower()], dtype=np.float64)
    v = np.asarray(up, dtype=np.float64)
    big = float(np.abs(v).max()) if v.shape == (3,) else 0.0
    if not (math.isfinite(big) and big > 0.0):
        raise ValueError(f"up must be a non-zero finite 3-vector, got {up!r}")
    v = v / big                  # scaled first: the norm of (1e300, 1e300, 0) would overflow
    return v / np.linalg.norm(v)


class _FrameMethod:
    """``Camera.frame(scene, up=...)`` fits a camera to a scene; ``camera.frame(width, height)`` is the
    older name of :meth:`Camera.image_plane` (the kernel upload still calls it)."""

    def __get__(self, obj: "Camera | None", owner: type) -> Any:
        def frame(*args: Any, **kwargs: Any) -> Any:
            if obj is not None and args and isinstance(args[0], (int, np.integer)):
                return obj.image_plane(*args, **kwargs)
            return frame_camera(*args, template=obj, **kwargs)
        frame.__doc__ = _FrameMethod.__doc__
        return frame


@dataclass(frozen=True)
class Camera:
    """A pinhole or thin-lens camera in the seed's conventions (SEMANTICS §3).

    ``direction`` is a view direction, not a look-at target (see :meth:`look_at` for that). ``fov``
    is the full horizontal angle in degrees. The image plane lies at ``focus`` along the view
    direction, so it is also the plane in focus; ``aperture`` is the lens radius (0 gives a pinhole).
    ``up`` is the world's up direction (the seed's Z by default): the image's vertical axis is the
    projection of ``up``. The defaults frame the seed's Cornell box.
    """

    position: Vec3 = (4.0, -55.0, 16.0)
    direction: Vec3 = (0.0, 1.0, 0.0)
    fov: float = 38.0
    aperture: float = 0.001
    focus: float = 27.0
    up: Vec3 = Z_UP

    frame = _FrameMethod()

    @classmethod
    def look_at(cls, position: Sequence[float], target: Sequence[float], *, up: str | Sequence[float] = "z",
                fov: float = 38.0, aperture: float = 0.0, focus: float | None = None) -> "Camera":
        """A camera at ``position`` looking at ``target``, focused on it unless ``focus`` is given.

        ``aperture`` defaults to 0 (a pinhole), so everything is sharp.
        """
        p = np.asarray(position, dtype=np.float64)
        t = np.asarray(target, dtype=np.float64)
        if not (np.abs(p).max() <= MAX_COORDINATE and np.abs(t).max() <= MAX_COORDINATE):   # NaN too
            raise ValueError(f"camera position and target must be finite and lie within +-{MAX_COORDINATE:g}")
        d = t - p
        dist = float(np.linalg.norm(d))
        if not (math.isfinite(dist) and dist > 0.0):
            raise ValueError("camera target must differ from its position")
        cam = cls(position=_vec(p), direction=_vec(d / dist), fov=float(fov), aperture=float(aperture),
                  focus=float(focus) if focus is not None else dist, up=_vec(up_vector(up)))
        cam.validate()
        return cam

    def with_(self, **changes: Any) -> "Camera":
        """A copy with some fields replaced (``None`` values are ignored), validated."""
        cam = replace(self, **{k: v for k, v in changes.items() if v is not None})
        cam.validate()
        return cam

    def validate(self, width: int = 1, height: int = 1) -> None:
        """Raise ValueError for a camera no renderer can use, or one whose frame would overflow float32.

        Called by :meth:`image_plane`, so every render checks it; ``width`` x ``height`` (pixels)
        also bounds the image plane of a tall image. The bounds are in :mod:`warp_spt.scene.limits`.
        """
        problem = camera_problem(self, width, height)
        if problem:
            raise ValueError(problem)

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit (view direction, image right, image up), float64.

        Looking straight along ``up`` or against it is well defined (the seed gave NaN looking
        down, Q12): for Z up, looking down puts +Y at the image's top and looking up puts -Y there
        (the seed's choice); for another up axis ``u``, ``cross(u, x)`` (or ``cross(u, y)``) plays +Y's role.
        """
        d = np.asarray(self.direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        u = up_vector(self.up)
        along = float(np.dot(d, u))
        if abs(along) >= 0.99999:
            top = _reference_top(u)            # image top when looking straight down
            right = np.cross(top, u)           # for Z up: exactly the seed's (1, 0, 0)
            up = top if along <= 0.0 else -top
        else:
            right = np.cross(d, u)
            right /= np.linalg.norm(right)
            up = np.cross(right, d)
            up /= np.linalg.norm(up)
        return d, right, up

    def image_plane(self, width: int, height: int) -> dict[str, np.ndarray]:
        """The image plane in world space (float64): origin, upper-left corner and pixel steps.

        Row 0 is the top of the image. Pixel (x, y) covers
        ``upper_left + (x + a) * x_step - (y + b) * y_step`` for a, b in [0, 1).
        """
        self.validate(width, height)
        d, right, up = self.axes()
        half = self.focus * math.tan(math.radians(self.fov) / 2.0)
        centre = np.asarray(self.position, dtype=np.float64) + d * self.focus
        upper_left = centre - right * half + up * half * height / width
        step = 2.0 * half / width
        return {
            "origin": np.asarray(self.position, dtype=np.float64),
            "upper_left": upper_left,
            "x_step": right * step,
            "y_step": up * step,
            "right": right,
            "up": up,
            "lens_radius": np.float64(self.aperture),
        }


def camera_problem(cam: Camera, width: int = 1, height: int = 1) -> str | None:
    """Why ``cam`` cannot be rendered exactly at ``width`` x ``height``, or None: the checks of
    :meth:`Camera.validate`, against float32 and the products the kernel's camera frame forms (a
    unit direction, focus x tan(fov/2), position + aperture offsets). Bounds checked before any
    vector is normalised, so nothing overflows on the host either."""
    try:
        pos, d, u = (tuple(float(v) for v in x) for x in (cam.position, cam.direction, cam.up))
        fov, focus, aperture = float(cam.fov), float(cam.focus), float(cam.aperture)
    except (TypeError, ValueError):
        return "camera values must be numbers (position, direction and up: three each)"
    if len(pos) != 3 or len(d) != 3 or len(u) != 3:
        return "camera position, direction and up must have three components each"
    if not all(math.isfinite(v) for v in (*pos, *d, *u, fov, focus, aperture)):
        return "camera values must be finite numbers"
    if max(abs(v) for v in pos) > MAX_CAMERA_COORDINATE:
        return f"camera position must lie within +-{MAX_CAMERA_COORDINATE:g}"
    for name, vec in (("view direction", d), ("up vector", u)):
        if not MIN_DIRECTION <= max(abs(v) for v in vec) <= MAX_COORDINATE:
            return (f"camera {name} must not be zero or huge: its largest component must lie in "
                    f"[{MIN_DIRECTION:g}, {MAX_COORDINATE:g}] in size")
    if not MIN_FOV <= fov < 180.0:
        return f"camera fov must be in [{MIN_FOV:g}, 180) degrees, got {fov:g}"
    if not MIN_FOCUS <= focus <= MAX_CAMERA_COORDINATE:
        return f"camera focus distance must lie in [{MIN_FOCUS:g}, {MAX_CAMERA_COORDINATE:g}], got {focus:g}"
    if not 0.0 <= aperture <= MAX_CAMERA_COORDINATE:
        return f"camera aperture must lie in [0, {MAX_CAMERA_COORDINATE:g}], got {aperture:g}"
    half = focus * math.tan(math.radians(fov) / 2.0) * max(1.0, height / width)
    if half > MAX_IMAGE_PLANE:
        return (f"camera image plane is too large for float32: focus x tan(fov/2) x max(1, height/width) "
                f"= {half:.3g}, at most {MAX_IMAGE_PLANE:g} (a smaller focus distance or fov)")
    return None


def _reference_top(u: np.ndarray) -> np.ndarray:
    """The image's top direction when looking straight down ``-u``: +Y for Z up (the seed's axes)."""
    if abs(u[2]) == 1.0 and u[0] == 0.0 and u[1] == 0.0:
        return np.array([0.0, 1.0, 0.0])
    t = np.cross(u, [1.0, 0.0, 0.0])
    if np.linalg.norm(t) < 1e-6:
        t = np.cross(u, [0.0, 1.0, 0.0])
    return t / np.linalg.norm(t)


def _vec(v: Sequence[float] | np.ndarray) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


# Framing: azimuth from the front towards the side, elevation above the horizon, in degrees; the
# box's projection fills 1/MARGIN of the frame's half-width or half-height.
AZIMUTH, ELEVATION, MARGIN = 35.0, 25.0, 1.05

# Named views (--view): (azimuth, elevation) in degrees. Azimuth 90 stands at the side that is on
# the image's right in the front view, as a CAD drawing's "right" view does.
VIEWS: dict[str, tuple[float, float]] = {"front": (0.0, 0.0), "back": (180.0, 0.0), "right": (90.0, 0.0),
                                         "left": (-90.0, 0.0), "top": (0.0, 90.0), "bottom": (0.0, -90.0)}

# A model is flat (a cut-out in a plane) when its thinnest extent is below this share of its widest.
FLAT_RATIO = 0.02


def front_vector(up: np.ndarray) -> np.ndarray:
    """The direction from a model towards its viewer for an up axis: -Y for Z up (the seed's camera
    stands at -Y), +Z for Y up (the glTF/OpenGL convention: models face +Z), +Z for X up."""
    for cand in ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)):
        f = np.asarray(cand) - np.dot(cand, up) * up
        if np.linalg.norm(f) > 0.5:
            return f / np.linalg.norm(f)
    return np.array([1.0, 0.0, 0.0])


def orbit_vector(up: str | Sequence[float], azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector from a model towards a camera at ``azimuth`` (from the front towards the right)
    and ``elevation`` (above the horizon), in degrees, for the up axis ``up``."""
    u = up_vector(up)
    front = front_vector(u)
    side = np.cross(u, front)
    az, el = math.radians(azimuth), math.radians(elevation)
    return math.cos(el) * (math.cos(az) * front + math.sin(az) * side) + math.sin(el) * u   # unit already


def flat_normal(scene: Scene, towards: np.ndarray) -> np.ndarray | None:
    """The unit normal of a flat model (a 2-D cut-out exported as a mesh: its thinnest extent below
    FLAT_RATIO of its widest, no spheres), on the side its faces face (or, for a sheet seen from both
    sides, the side of ``towards``); None for a solid model."""
    if len(scene.spheres) or not any(len(m.indices) for m in scene.meshes):
        return None
    if scene.instanced:
        found = _flat_by_moments(scene)
        if found is None:
            return None
        n, facing, scale = found
    else:
        points = [m.positions[np.unique(m.indices)].astype(np.float64) for m in scene.meshes if len(m.indices)]
        p = np.concatenate(points)
        p -= p.mean(0)
        _, sv, vt = np.linalg.svd(p, full_matrices=False)
        if len(sv) < 3 or not sv[0] > 0 or sv[2] > FLAT_RATIO * sv[0]:
            return None
        n = vt[2]
        facing = sum(float(np.sum(np.cross(m.positions[m.indices[:, 1]] - m.positions[m.indices[:, 0]],
                                          m.positions[m.indices[:, 2]] - m.positions[m.indices[:, 0]]) @ n))
                     for m in scene.meshes if len(m.indices))
        scale = max(float(sv[0]) ** 2 / len(p), 1e-300)
    side = facing if abs(facing) > 1e-6 * scale else float(np.dot(n, towards))
    return n if side >= 0.0 else -n


def _flat_by_moments(scene: Scene) -> tuple[np.ndarray, float, float] | None:
    """flat_normal's (normal, facing, scale) for a scene with instances, from each mesh's vertex
    moments and summed face normals mapped by every placement (no copies): the same principal axes
    as the SVD of every placed vertex, and the same sum of winding normals (a placement maps a face's
    cross product by |det A| A^-T, its winding reversed when A mirrors)."""
    count, first, second, faces = 0.0, np.zeros(3), np.zeros((3, 3)), np.zeros(3)
    for m in scene.meshes:
        if not len(m.indices):
            continue
        p = m.positions[np.unique(m.indices)].astype(np.float64)
        s1, s2 = p.sum(0), p.T @ p
        q = m.positions.astype(np.float64)
        c = np.cross(q[m.indices[:, 1]] - q[m.indices[:, 0]], q[m.indices[:, 2]] - q[m.indices[:, 0]]).sum(0)
        xs = np.eye(4)[None] if m.transforms is None else m.transforms
        a, t = xs[:, :3, :3], xs[:, :3, 3]
        a_s1 = a @ s1                                               # (I, 3)
        count += len(p) * len(xs)
        first += (a_s1 + len(p) * t).sum(0)
        second += (np.einsum("nij,jk,nlk->il", a, s2, a) + np.einsum("ni,nj->ij", a_s1, t)
                   + np.einsum("ni,nj->ij", t, a_s1) + len(p) * np.einsum("ni,nj->ij", t, t))
        det = np.abs(np.linalg.det(a))
        faces += np.einsum("n,nji,j->i", det, np.linalg.inv(a), c)    # sum of |det A| A^-T c
    scatter = second - np.outer(first, first) / count
    w, v = np.linalg.eigh(scatter)                                   # ascending: w[2] is the widest
    sv = np.sqrt(np.maximum(w[::-1], 0.0))
    if not sv[0] > 0 or sv[2] > FLAT_RATIO * sv[0]:
        return None
    n = v[:, 0]
    return n, float(faces @ n), max(float(sv[0]) ** 2 / count, 1e-300)


# A scene whose centre lies farther from the origin than this many times its size is recentred
# before rendering (warp_spt.scene.recentre) and framed in that frame.
RECENTRE_RATIO = 4.0


def exact_bounds(scene: Scene) -> np.ndarray:
    """(2, 3) float64 bounds of the positions as parsed (``Scene.bounds`` gives them rounded to
    float32, where a 2-unit model 1e9 from the origin is a point)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for m in scene.meshes:
        b = m.world_bounds(rounded=False)
        if b is not None:
            lo, hi = np.minimum(lo, b[0]), np.maximum(hi, b[1])
    if len(scene.spheres):
        s = scene.spheres.astype(np.float64)
        lo, hi = np.minimum(lo, (s[:, :3] - s[:, 3:4]).min(0)), np.maximum(hi, (s[:, :3] + s[:, 3:4]).max(0))
    return np.stack([lo, hi])


def far_centre(scene: Scene, ratio: float = RECENTRE_RATIO) -> np.ndarray | None:
    """The centre of a scene that lies far from the origin (farther than ``ratio`` times its size,
    in float64), or None for a scene near the origin."""
    b = exact_bounds(scene)
    if not np.all(np.isfinite(b)):          # nothing to draw (an animation's frame that hides everything)
        return None
    size = float(np.max(b[1] - b[0]))
    centre = 0.5 * (b[0] + b[1])
    return centre if size > 0.0 and float(np.max(np.abs(centre))) > ratio * size else None


# A base (a ground or plinth: faces lying in the scene's lowest plane along the up axis) is left out
# of the framing when it is this many times wider than everything else.
BASE_RATIO = 3.0
# Up-axis cue of a scan: its faces in the lowest XY plane cover at least this share of the bounds'
# XY rectangle (a bust's cut base), it has no such base in XZ, and it is at least this tall for its width.
SCAN_BASE_SHARE, SCAN_MIN_HEIGHT = 0.05, 0.5
# A scan's cut base is rarely exactly one plane of the file's axes: its faces count when they lie
# within BASE_BAND of the scene's size above the lowest point and face within BASE_TILT degrees of
# the axis (a base tilted by 1-2 degrees, a few stray points below it).
BASE_BAND, BASE_TILT = 0.02, 10.0
# A ground under everything (the base covers this share of the rectangle) is a Z-up cue at this
# height for its width too: a room or a set on a floor, not a relief (whose depth is a few percent).
GROUND_SHARE, GROUND_MIN_HEIGHT = 0.9, 0.25
# Standing (PLY files, which have no up convention): the points within SUPPORT_BAND of the height
# above the lowest one are what the model stands on; their convex hull, on a SUPPORT_GRID-row
# raster, must hold the surface's centroid, and one axis's hull must be SUPPORT_RATIO times the other's.
SUPPORT_BAND, SUPPORT_GRID, SUPPORT_RATIO, SUPPORT_MIN_SHARE = 0.02, 64, 2.0, 0.02
# ... and be at least this tall for its width along it (a relief lying on its back stands too)
STAND_MIN_HEIGHT = 0.25


def _bottom_faces(scene: Scene, axis: np.ndarray, tol: float = 1e-4) -> Iterator[tuple]:
    """Per mesh, a batch of placements at a time: (world positions (B, V, 3) float64, triangles
    (F, 3), mask (B, F) of the triangles that lie, all three corners within ``tol`` of the scene's
    size, in the scene's lowest plane along ``axis``). A batch is one array product over its
    placements (B x max(V, F) at most 2^18 rows), so that 200,000 instances cost microseconds each,
    not a Python loop's tens."""
    b = scene.bounds
    low = float(np.min(b @ axis)) if len(scene.meshes) else 0.0
    eps = tol * max(float(np.max(b[1] - b[0])), 1e-30)
    for m in scene.meshes:
        tri = np.asarray(m.indices)
        p = np.asarray(m.positions, dtype=np.float64)
        if m.transforms is None:
            batches = [p[None]]
        else:
            step = max(1, (1 << 18) // max(len(p), len(tri), 1))
            batches = (np.matmul(p, x[:, :3, :3].transpose(0, 2, 1)) + x[:, None, :3, 3]
                       for x in (m.transforms[k:k + step] for k in range(0, len(m.transforms), step)))
        for world in batches:
            h = world @ axis
            mask = np.all(h[:, tri] <= low + eps, axis=2) if len(tri) else np.zeros((len(world), 0), bool)
            yield world, tri, mask


def base_share(scene: Scene, up: str | Sequence[float], tolerant: bool = False) -> float:
    """The area of the faces lying in the scene's lowest plane along ``up`` over the area of the
    bounds' rectangle across ``up`` (0: no flat base; a ground under everything: about 1).
    ``tolerant``: the faces within BASE_BAND of it facing within BASE_TILT of ``up``, by their
    footprint across it (a scan's cut base, slightly tilted or rough)."""
    u = up_vector(up)
    b = scene.bounds
    across = [k for k in range(3) if abs(u[k]) < 0.5]
    rect = float(np.prod((b[1] - b[0])[across])) if len(across) == 2 else 0.0
    if not rect > 0.0:
        return 0.0
    area = 0.0
    for world, tri, mask in _bottom_faces(scene, u, BASE_BAND if tolerant else 1e-4):
        if mask.any():
            rows, faces = np.nonzero(mask)
            t = world[rows[:, None], tri[faces]]                  # (N, 3, 3): the base's triangles
            n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            if tolerant:
                along = np.abs(n @ u)
                area += 0.5 * float(along[along >= math.cos(math.radians(BASE_TILT)) * np.linalg.norm(n, axis=1)].sum())
            else:
                area += 0.5 * float(np.linalg.norm(n, axis=1).sum())
    return area / rect


def looks_z_up(scene: Scene) -> bool:
    """A model written Z up: it stands on a flat base in the XY plane (its lowest faces along Z cover
    SCAN_BASE_SHARE of its XY rectangle, within BASE_BAND and BASE_TILT: ``base_share(tolerant=True)``),
    has none in XZ (lowest along Y), and is either at least SCAN_MIN_HEIGHT times as tall (Z) as it is
    wide (a scanned bust on its cut base), or the base is a ground much wider than what stands on it,
    or a ground under everything (GROUND_SHARE) at least GROUND_MIN_HEIGHT as tall as wide (a set on
    a floor); so a flat relief whose back faces -Z is not taken for one."""
    if len(scene.spheres):
        return False
    z = base_share(scene, "z", tolerant=True)
    if not z >= SCAN_BASE_SHARE > base_share(scene, "y", tolerant=True):
        return False
    ext = np.ptp(scene.bounds, axis=0)
    wide = max(ext[0], ext[1])
    return bool(ext[2] >= SCAN_MIN_HEIGHT * wide or (z >= GROUND_SHARE and ext[2] >= GROUND_MIN_HEIGHT * wide)) \
        or subject_bounds(scene, "z") is not None


def _mass(scene: Scene) -> tuple[np.ndarray, np.ndarray] | None:
    """(every vertex (V, 3) float64, the surface's area centroid (3,)) of a scene of plain meshes, or
    None (instances, spheres, no area). The centroid is of at most 2^16 triangles, every k-th: a
    scan of millions costs what 65,536 triangles do."""
    if len(scene.spheres) or scene.instanced or not scene.meshes:
        return None
    pts = np.concatenate([np.asarray(m.positions, np.float64) for m in scene.meshes])
    total = sum(len(m.indices) for m in scene.meshes)
    step = max(1, -(-total // (1 << 16)))
    tris = [np.asarray(m.positions, np.float64)[m.indices[::step]] for m in scene.meshes if len(m.indices)]
    if not tris:
        return None
    t = np.concatenate(tris)
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    if not area.sum() > 0:
        return None
    return pts, (t.mean(1) * area[:, None]).sum(0) / area.sum()


def support(scene: Scene, up: str | Sequence[float], mass=None) -> tuple[float, bool]:
    """What the scene stands on with ``up`` up: (the convex hull of its points within SUPPORT_BAND of
    its height above the lowest, over the bounds' rectangle across ``up``; whether that hull holds the
    surface's area centroid, i.e. it stands without tipping over). (0, False) for instanced meshes,
    spheres or no area. The hull is of the points' extremes per row of a SUPPORT_GRID-row raster, so
    a scan of millions of points costs a few array passes. ``mass``: :func:`_mass`'s, if known."""
    u = up_vector(up)
    mass = _mass(scene) if mass is None else mass
    across = [k for k in range(3) if abs(u[k]) < 0.5]
    if mass is None or len(across) != 2:
        return 0.0, False
    pts, centre = mass
    lo, hi = pts.min(0), pts.max(0)
    centroid = (centre - lo)[across]              # coordinates from the bounds' corner: no cancellation far off
    rect = float(np.prod((hi - lo)[across]))
    if not rect > 0:
        return 0.0, False
    h = pts @ u
    foot = (pts[h <= h.min() + SUPPORT_BAND * (h.max() - h.min())] - lo)[:, across]
    a0, a1 = 0.0, hi[across[0]] - lo[across[0]]
    row = np.minimum(((foot[:, 0] - a0) / max(a1 - a0, 1e-300) * SUPPORT_GRID).astype(np.int64), SUPPORT_GRID - 1)
    first, last = np.full(SUPPORT_GRID, np.inf), np.full(SUPPORT_GRID, -np.inf)
    np.minimum.at(first, row, foot[:, 1])
    np.maximum.at(last, row, foot[:, 1])
    xmin, xmax = np.full(SUPPORT_GRID, np.inf), np.full(SUPPORT_GRID, -np.inf)
    np.minimum.at(xmin, row, foot[:, 0])
    np.maximum.at(xmax, row, foot[:, 0])
    used = np.isfinite(first)
    corners = np.concatenate([np.column_stack([xmin[used], first[used]]), np.column_stack([xmax[used], last[used]]),
                              np.column_stack([xmin[used], last[used]]), np.column_stack([xmax[used], first[used]])])
    hull = _convex_hull(corners)
    if len(hull) < 3:
        return 0.0, False
    x, y = hull[:, 0], hull[:, 1]
    hull_area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    edges = np.roll(hull, -1, axis=0) - hull
    inside = bool(np.all(edges[:, 0] * (centroid[1] - y) - edges[:, 1] * (centroid[0] - x) >= 0))
    return hull_area / rect, inside


def _convex_hull(p: np.ndarray) -> np.ndarray:
    """The convex hull of 2-D points, counter-clockwise (Andrew's monotone chain)."""
    p = np.unique(p, axis=0)
    if len(p) < 3:
        return p

    def chain(points):
        out: list = []
        for q in points:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (q[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (q[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(q)
        return out

    lower, upper = chain(p), chain(p[::-1])
    return np.array(lower[:-1] + upper[:-1])


def stands_up(scene: Scene, strict: bool = False) -> str | None:
    """The axis, ``"z"`` or ``"y"``, the scene clearly stands on (:func:`support`): it stands without
    tipping along that axis, is at least STAND_MIN_HEIGHT as tall as wide along it, its support
    is at least SUPPORT_MIN_SHARE of the rectangle and
    SUPPORT_RATIO times the other axis's (or the other tips over); None when the shape does not tell
    (the rule of PLY files, which have no up convention: a horse on its hooves, Z up). ``strict`` (a
    format whose convention is Y up, OBJ): ``"z"`` only when it also tips over with Y up (a bust
    whose cut base is open, a horse), else None."""
    mass = _mass(scene)
    (zs, zok), (ys, yok) = support(scene, "z", mass), support(scene, "y", mass)
    ext = np.ptp(scene.bounds, axis=0)
    zok = zok and ext[2] >= STAND_MIN_HEIGHT * max(ext[0], ext[1])
    if strict:
        return "z" if zok and not yok and zs >= max(SUPPORT_MIN_SHARE, SUPPORT_RATIO * ys) else None
    yok = yok and ext[1] >= STAND_MIN_HEIGHT * max(ext[0], ext[2])
    if zok and zs >= SUPPORT_MIN_SHARE and (not yok or zs >= SUPPORT_RATIO * ys):
        return "z"
    if yok and ys >= SUPPORT_MIN_SHARE and (not zok or ys >= SUPPORT_RATIO * zs):
        return "y"
    return None


def subject_bounds(scene: Scene, up: str | Sequence[float]) -> np.ndarray | None:
    """The bounds of what stands on a base (see BASE_RATIO), to frame instead of the whole scene, or
    None when the scene has no base that much wider than the rest."""
    u = up_vector(up)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    blo, bhi = np.full(3, np.inf), np.full(3, -np.inf)
    based = False
    for world, tri, mask in _bottom_faces(scene, u):
        if not len(tri):
            continue
        based = based or bool(mask.any())
        corners = world.astype(np.float32).astype(np.float64)[:, tri]     # (B, F, 3, 3)
        for sel, (a, z) in ((~mask, (lo, hi)), (mask, (blo, bhi))):
            if sel.any():
                q = corners[sel].reshape(-1, 3)
                a[:] = np.minimum(a, q.min(0))
                z[:] = np.maximum(z, q.max(0))
    if not based:
        return None
    if len(scene.spheres):
        sp = scene.spheres.astype(np.float32).astype(np.float64)
        lo, hi = np.minimum(lo, (sp[:, :3] - sp[:, 3:4]).min(0)), np.maximum(hi, (sp[:, :3] + sp[:, 3:4]).max(0))
    if not np.all(np.isfinite(lo)):
        return None                                   # nothing but the base
    rest, base = float(np.max(hi - lo)), float(np.max(bhi - blo))
    if not base > BASE_RATIO * rest:
        return None
    return np.stack([lo, hi])


def _box(scene_or_bounds: Scene | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bounds, origin): a far scene's float64 bounds relative to its centre (the frame a render
    recentres it to) and that centre; otherwise the bounds as the engine sees them and 0."""
    origin = np.zeros(3)
    if isinstance(scene_or_bounds, Scene):
        far = far_centre(scene_or_bounds)
        if far is not None:
            origin = far
            b = exact_bounds(scene_or_bounds) - far
        else:
            b = scene_or_bounds.bounds
    else:
        b = np.asarray(scene_or_bounds, np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)):
        raise ValueError("framing needs a scene with geometry (finite bounds)")
    return b, origin


def frame_camera(scene: Scene | np.ndarray, up: str | Sequence[float] | None = None, *, fov: float | None = None,
                 aspect: float = 1.0, margin: float = MARGIN, template: Camera | None = None,
                 azimuth: float = AZIMUTH, elevation: float = ELEVATION, target: Sequence[float] | None = None,
                 towards: Sequence[float] | None = None) -> Camera:
    """A camera that shows all of ``scene`` (or (2, 3) bounds), by default a three-quarter view from
    the front.

    ``aspect`` is width / height of the image. ``fov`` defaults to the template's (the seed's 38°);
    ``up`` to the template's up axis (Z). The camera looks at ``target`` (default: the bounds'
    centre) from ``azimuth``/``elevation`` (degrees, see :func:`orbit_vector`) or along ``towards``
    (a vector from the target to the camera), as close as shows the whole box. The result is a
    pinhole focused at the target.
    """
    if isinstance(aspect, bool) or not isinstance(aspect, (int, float, np.integer, np.floating)) \
            or not 0.0 < aspect < 1e300:       # an int such as 10**400 compares before float() overflows
        raise ValueError(f"aspect must be a positive finite number (width / height), got {aspect!r:.40}")
    aspect = float(aspect)
    b, origin = _box(scene)
    base = template or Camera()
    u = up_vector(up if up is not None else base.up)
    fov = float(fov if fov is not None else base.fov)
    if towards is None:
        towards_camera = orbit_vector(u, azimuth, elevation)
    else:
        towards_camera = np.asarray(towards, dtype=np.float64)
        towards_camera = towards_camera / np.linalg.norm(towards_camera)
    centre = 0.5 * (b[0] + b[1]) if target is None else np.asarray(target, dtype=np.float64) - origin
    probe_cam = Camera(position=tuple(centre), direction=tuple(-towards_camera), fov=fov, focus=1.0,
                       aperture=0.0, up=tuple(u))
    d, right, img_up = probe_cam.axes()
    corners = np.array([[b[i][0], b[j][1], b[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]) - centre
    tx = math.tan(math.radians(fov) / 2.0) / margin
    ty = tx / aspect
    x, y, z = corners @ right, corners @ img_up, corners @ d
    dist = float(max(np.max(np.abs(x) / tx - z), np.max(np.abs(y) / ty - z)))
    size = float(np.linalg.norm(b[1] - b[0]))
    # at least MIN_FOCUS away (a scene smaller than that is framed as a dot, not refused)
    dist = max(dist, float(np.max(-z)) + 1e-3 * size, 1e-6 * max(size, float(np.max(np.abs(centre)))), 2 * MIN_FOCUS)
    return Camera(position=tuple(float(v) for v in origin + (centre - d * dist)), direction=tuple(float(v) for v in d),
                  fov=fov, aperture=0.0, focus=dist, up=tuple(float(v) for v in u))
