"""The ``--studio`` preset: a neutral sky, a ground plane under the model and a key light.

It adds generated geometry to a loaded :class:`Scene` (the user's files are never edited): a large
square ground under the model's bounds (along the up axis) in a mid-grey diffuse material, and an
emissive sphere above, to the left and in front of the model as the camera sees it, sized and placed
from the bounds, so a bare scanned model renders like a product shot with a soft shadow, from
whichever side it is seen (a camera below the ground sees the model without it). The key light is an ordinary emitter: renders find it by path tracing
(and by light sampling, where the integrator offers it). When the user brings lights of their own
(a sun, a lamp, a glTF file's lights, an environment map) they are the key: the ground and the sky
stay, the sphere is left out (``key=False``), so it neither shows in the frame nor shades the ground.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from warp_spt.scene.camera import AZIMUTH, ELEVATION, Camera, front_vector, orbit_vector, up_vector
from warp_spt.scene.limits import MAX_TRIANGLE_EDGE
from warp_spt.scene.model import Material, MaterialTable, MeshData, Scene
from warp_spt.scene.sky import Sky

# Levels: a white (albedo 1) surface facing the key gets about 0.9 (no clipping in the seed's tone
# map, which reaches 255 only well above 1); the clay (0.6) about 0.55; the backdrop is darker than
# the clay (the sky 0.2, the ground 0.4 x its light), so a white or a grey model stands out from it.
SKY = (0.2, 0.2, 0.2)             # a neutral grey sky
# the sky when the user's lights are the key (no key sphere): half the key's sky, so that a unit sun
# (irradiance 1) stands to the fill about as the key stands to SKY
FILL_SKY = (0.1, 0.1, 0.1)
GROUND_ALBEDO = 0.4
GROUND_HALF_SIZE = 40.0           # in units of the model's bounding radius
LIGHT_DISTANCE, LIGHT_RADIUS = 3.0, 1.5    # in units of the model's bounding radius: a big, soft key
FRAME_MARGIN = 1e-3               # of the radius: rounding, no more (the camera sees only its frustum)
LIGHT_EMISSION = 2.0              # about 3.5x the sky's contribution on a surface facing it
LIGHT_NAME = "studio light"       # the key light's material row


def studio_sky(key: bool = True) -> Sky:
    """The studio's neutral constant sky: with its key light (``key``), or the dimmer fill beside
    the user's lights."""
    return Sky.constant(*(SKY if key else FILL_SKY))


def add_studio(scene: Scene, up: str | Sequence[float] = "z", camera: Camera | None = None, *, key: bool = True,
               bounds: np.ndarray | None = None, aspect: float | None = None) -> Scene:
    """``scene`` plus a ground plane and (``key``) a key-light sphere placed from its bounds and ``camera``.

    The light keeps its place relative to the camera: where the default framing sees it (in front
    of the model, to the image's left and top), whatever side the camera is on, so turning the view
    keeps the model lit. Without a camera it stands where the default framing would see it so.
    ``key=False`` is the studio lit by the user's lights (``conventions.STUDIO_LIGHTS``): the
    ground, no sphere (its material row is added all the same, so a viewer can put the key back,
    :func:`with_key`, without renumbering materials). ``bounds``: what to stand the ground under
    and place the key from (an animation's union over its frames); default the scene's. ``aspect``
    (image width / height) with ``camera``: the key is kept out of that frame (:func:`key_sphere`)."""
    u = up_vector(up)
    b = scene.bounds if bounds is None else np.asarray(bounds, np.float64)
    centre = 0.5 * (b[0] + b[1])
    radius = max(0.5 * float(np.linalg.norm(b[1] - b[0])), 1e-6)
    front = front_vector(u)
    side = np.cross(u, front)
    low = float(np.min((b - centre) @ u))        # the bounds' lowest point along up, relative to centre
    floor = centre + u * (low - 1e-3 * radius)    # just under the model: no coplanar faces
    # the quad's triangles' longest edge (its diagonal, 2 sqrt(2) half) within the triangle bound: a model
    # over about 1.7e7 across had a ground the loader's own bound refuses
    half = min(GROUND_HALF_SIZE * radius, 0.99 * MAX_TRIANGLE_EDGE / (2.0 * np.sqrt(2.0)))
    e1, e2 = front * half, side * half
    quad = np.array([floor - e1 - e2, floor + e1 - e2, floor + e1 + e2, floor - e1 + e2], dtype=np.float64)
    # wind the quad to face up
    faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
    if np.dot(np.cross(quad[1] - quad[0], quad[2] - quad[0]), u) < 0:
        faces = faces[:, ::-1].copy()
    ground_row = len(scene.materials)
    ground = MeshData(name="studio ground", positions=quad.astype(np.float32), indices=faces,
                      corner_uv=np.zeros((2, 3, 2), np.float32), corner_normal=None,
                      face_material=np.full(2, ground_row, np.int32), prop=True)
    below = camera is not None and float(np.dot(np.asarray(camera.position) - floor, u)) < 0.0
    dressed = replace(scene, meshes=[*scene.meshes, *([] if below else [ground])],   # seen from below: no floor
                      materials=_with_rows(scene.materials))
    return with_key(dressed, key_sphere(b, u, camera, aspect) if key else None)


def key_sphere(bounds: np.ndarray, up: str | Sequence[float], camera: Camera | None = None,
               aspect: float | None = None) -> np.ndarray:
    """The studio's key light for ``bounds`` seen by ``camera``: (4,) float32, centre and radius.

    With ``aspect`` (image width / height), a light that would show in ``camera``'s frame (a white
    patch in its top-left corner: a 4:3 frame moves the camera back from a tall model) is moved out
    of it along its line from the model's centre, its radius scaled with its distance, so the model
    sees it under the same solid angle and is lit the same (:func:`_out_of_frame`)."""
    u = up_vector(up)
    b = np.asarray(bounds, np.float64)
    centre = 0.5 * (b[0] + b[1])
    radius = max(0.5 * float(np.linalg.norm(b[1] - b[0])), 1e-6)
    front = front_vector(u)
    side = np.cross(u, front)
    key_dir = 0.7 * front - 0.6 * side + 1.2 * u       # as the default framing sees it
    if camera is not None:
        key_dir = _as_seen_by(key_dir, Camera.look_at(orbit_vector(u, AZIMUTH, ELEVATION), (0, 0, 0), up=u), camera)
    offset, light_radius = LIGHT_DISTANCE * radius * key_dir / np.linalg.norm(key_dir), LIGHT_RADIUS * radius
    if camera is not None and aspect:
        k = _out_of_frame(centre, offset, light_radius, camera, aspect)
        offset, light_radius = k * offset, k * light_radius
    return np.array([*(centre + offset), light_radius], dtype=np.float32)


def _out_of_frame(centre: np.ndarray, offset: np.ndarray, radius: float, camera: Camera, aspect: float,
                  margin: float = FRAME_MARGIN) -> float:
    """The least k >= 1 (to 1e-3) that puts a sphere at ``centre + k offset`` of radius ``k radius``
    wholly outside what ``camera`` sees of an ``aspect`` frame, with ``margin`` of the radius to
    spare; 1 where it already is (the light is left where it was), 1 too where no k up to 64 does it."""
    d, right, top = camera.axes()
    tx = float(np.tan(np.radians(camera.fov) / 2.0))        # the fov is the horizontal one
    ty = tx / aspect
    c0 = np.asarray(centre, np.float64) - np.asarray(camera.position, np.float64)
    v = np.asarray(offset, np.float64)
    edges = [d + sx * tx * right + sy * ty * top for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))]

    def clear(k: float) -> bool:
        return _distance_to_pyramid(c0 + k * v, edges) > (1.0 + margin) * k * radius

    if clear(1.0):
        return 1.0
    hi = 2.0
    while not clear(hi):
        hi *= 2.0
        if hi > 64.0:
            return 1.0
    lo = hi / 2.0
    while hi - lo > 1e-3:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if clear(mid) else (mid, hi)
    return hi


def _distance_to_pyramid(p: np.ndarray, edges: list) -> float:
    """The distance from ``p`` to the infinite pyramid from the origin spanned by the four ``edges``
    (in order around it): 0 inside; else the least over its faces (where ``p``'s projection falls
    within one), its edge rays and its apex."""
    units = [e / np.linalg.norm(e) for e in edges]
    normals = [np.cross(units[i], units[(i + 1) % 4]) for i in range(4)]
    normals = [-n / np.linalg.norm(n) if n @ sum(units) > 0 else n / np.linalg.norm(n) for n in normals]  # outward
    if all(n @ p <= 0.0 for n in normals):
        return 0.0
    best = float(np.linalg.norm(p))
    for i, n in enumerate(normals):
        e1, e2 = units[i], units[(i + 1) % 4]
        t = float(p @ e1)
        if t > 0.0:
            best = min(best, float(np.linalg.norm(p - t * e1)))
        h = float(n @ p)
        if h > 0.0:
            q = p - h * n                                  # in the face's plane: q = a e1 + b e2
            a, b = np.linalg.lstsq(np.stack([e1, e2], 1), q, rcond=None)[0]
            if a >= 0.0 and b >= 0.0:
                best = min(best, h)
    return best


def with_key(scene: Scene, sphere: np.ndarray | None) -> Scene:
    """A studio scene (:func:`add_studio`'s) with its key light ``sphere``, or without one (None):
    the studio's one rule for the user's lights, that they replace the key (a viewer's page turning
    its sun on or off goes through here)."""
    row = scene.materials.names.index(LIGHT_NAME, len(scene.materials.names) - 2)
    keep = scene.sphere_material != row
    spheres, rows = scene.spheres[keep], scene.sphere_material[keep]
    if sphere is not None:
        spheres = np.concatenate([spheres, np.asarray(sphere, np.float32).reshape(1, 4)])
        rows = np.concatenate([rows, [row]])
    return replace(scene, spheres=spheres.astype(np.float32), sphere_material=rows.astype(np.int32))


def _as_seen_by(v: np.ndarray, seen: Camera, camera: Camera) -> np.ndarray:
    """The vector that ``camera`` sees as ``seen`` sees ``v``: same components along the view
    direction, image right and image up."""
    axes, to = seen.axes(), camera.axes()
    return sum(float(np.dot(v, a)) * b for a, b in zip(axes, to))


def _with_rows(t: MaterialTable) -> MaterialTable:
    """The table plus two rows: the ground (grey, diffuse) and the light (emissive, black)."""
    grey, black = (GROUND_ALBEDO,) * 3, (0.0, 0.0, 0.0)
    plain = dict(refract=black, roughness=1.0, fuzz=0.0, ior=1.0)    # diffuse only, no glass
    return t.with_rows([Material("studio ground", diffuse=grey, reflect=grey, emission=black, **plain),
                        Material(LIGHT_NAME, diffuse=black, reflect=black, emission=(LIGHT_EMISSION,) * 3, **plain)])
