"""The light table: every light the scene has, each kind's entries in turn (``registry.KINDS``
order), one discrete distribution to choose among them, and the device struct ``Lights`` holding
the choice and each kind's data (``lights.<kind name>``).

The choice probability of an entry is proportional to **emitting area x mean emitted radiance**
(mean over the RGB channels; for a textured emitter, over the texture on that triangle, estimated
at a few points). For the seed's diffuse emitters that is proportional to the emitted power: a
two-sided triangle of area A radiates 2*pi*A*L, a sphere pi*4*pi*r^2*L, and the sky is weighed as
a sphere of the scene's radius seen from inside. Power, rather than area alone, sends few samples
to dim emitters; the estimate is unbiased whatever the weights, because MIS evaluates the density
with the same table that sampling draws from (an emitter the table misses is simply found by BSDF
sampling).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.emitters.base import Weighed, device_array
from warp_spt.emitters.registry import KINDS
from warp_spt.scene.model import Scene
from warp_spt.scene.sky import Z_UP, Sky

KindInts = wp.types.vector(length=len(KINDS), dtype=wp.int32)
# the kinds with differentiable parameters (``LightKind.params``): the ``kind`` of their ParamInfo
# (``warp_spt.diff.params``), whose ``index`` is the row of the parameter array
PARAMETER_KINDS = tuple(k.name for k in KINDS if k.params)
# their fields whose derivative needs a pathwise kernel (``LightKind.pathwise``: a light's position moves directions)
PATHWISE_FIELDS = {k.name: k.pathwise for k in KINDS if k.params}


def _lights_struct():
    """``Lights``: the choice (``cdf``, ``entry_prob``, ``num_entries``; ``first``/``count``: each
    kind's entries, in KINDS order) and one field per kind, its ``data`` struct."""
    fields = {"cdf": wp.array(dtype=wp.float32),           # cumulative choice probabilities, last = 1
              "num_entries": int,
              "entry_prob": wp.array(dtype=wp.float32),    # choice probability per entry
              "first": KindInts,
              "count": KindInts}
    fields.update({k.name: k.data for k in KINDS})
    cls = type("Lights", (), {"__annotations__": fields, "__module__": __name__, "__qualname__": "Lights",
                              "__doc__": _lights_struct.__doc__})
    return wp.struct(cls)


Lights = _lights_struct()


@wp.func
def pick_entry(lights: Lights, u: float) -> int:
    """The first table entry whose cumulative probability exceeds u (zero-weight entries never)."""
    lo = int(0)
    hi = lights.num_entries - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if lights.cdf[mid] > u:
            hi = mid
        else:
            lo = mid + 1
    return lo


@wp.func
def reuse_pick(lights: Lights, u: float) -> float:
    """The uniform number left in ``u`` once ``pick_entry`` has used it: (u - cdf before) / prob, again
    uniform on [0, 1) for the chosen entry (pbrt-v4's "remapped" sample), or -1 where the entry's
    probability is under 2**-12 and too few of u's 24 bits would be left."""
    e = pick_entry(lights, u)
    prob = lights.entry_prob[e]
    if prob < 2.44140625e-4:
        return -1.0
    lo = float(0.0)
    if e > 0:
        lo = lights.cdf[e - 1]
    return wp.clamp((u - lo) / prob, 0.0, 0.99999994)


# ---------------------------------------------------------------------------------------------
# Host side


def table_key(sky: Sky, camera_up=Z_UP) -> tuple:
    """The key under which a DeviceScene caches its light table for this sky and camera up."""
    return (sky.kind, tuple(sky.color), tuple(sky.zenith), tuple(sky.nadir), sky.env, sky.strength,
            sky.rotate, sky.background, sky.plus, sky.up_axis(camera_up))


def light_table(dev, sky: Sky, camera_up=Z_UP) -> Lights:
    """The device light table of a DeviceScene under ``sky`` (built once per scene and sky); the
    gradient sky follows ``sky.up``, else ``camera_up`` (pass the camera's ``up``)."""
    key = table_key(sky, camera_up)
    weights = dev.light_cache("weights", lambda: {k.name: k.weigh(dev.scene, sky) for k in KINDS if k.cache})
    return dev.light_cache(key, lambda: _upload(weights, dev.scene, sky, key[-1], dev.device))


def _upload(cached: dict[str, Weighed], scene: Scene, sky: Sky, up: tuple[float, float, float],
            device: str) -> Lights:
    weighed = [cached[k.name] if k.cache else k.weigh(scene, sky) for k in KINDS]
    wall = np.concatenate([w.weights for w in weighed])
    n = len(wall)
    if n:
        cdf = (np.cumsum(wall) / wall.sum()).astype(np.float32)
        cdf[-1] = 1.0
        prob = np.diff(np.concatenate([[0.0], cdf.astype(np.float64)]))   # exactly what pick_entry does
    else:
        cdf, prob = np.zeros(1, np.float32), np.zeros(0)
    L = Lights()
    L.cdf = device_array(cdf, wp.float32, np.float32, device)
    L.entry_prob = device_array(prob, wp.float32, np.float32, device)
    L.num_entries = n
    first, firsts, counts = 0, [], []
    for k, w in zip(KINDS, weighed):
        count = len(w.weights)
        setattr(L, k.name, k.upload(w.payload, prob[first:first + count], scene, sky, up, device))
        firsts.append(first)
        counts.append(count)
        first += count
    L.first, L.count = KindInts(*firsts), KindInts(*counts)
    return L


def _copy(struct, value):
    """A shallow copy of a Warp struct instance (its arrays shared)."""
    out = struct()
    for name in struct.vars:
        setattr(out, name, getattr(value, name))
    return out


def parameter_arrays(lights: Lights) -> dict[str, wp.array]:
    """The kinds' differentiable parameter arrays by kind name (``LightKind.params``: the sky's
    colours under "sky")."""
    return {k.name: getattr(getattr(lights, k.name), k.params) for k in KINDS if k.params}


def alias_parameters(lights: Lights, alias) -> Lights:
    """A copy of ``lights`` whose parameter arrays are ``alias(array)`` (a backward pass's view with a
    gradient buffer of its own); the rest is shared."""
    out = _copy(Lights, lights)
    for k in KINDS:
        if k.params:
            data = _copy(k.data, getattr(lights, k.name))
            setattr(data, k.params, alias(getattr(data, k.params)))
            setattr(out, k.name, data)
    return out


def alias_field(lights: Lights, kind: str, field: str, alias) -> Lights:
    """A copy of ``lights`` whose kind ``kind`` has array ``field`` replaced by ``alias(array)`` (the
    environment map's texels, differentiated only when asked: a buffer of the map's size per tile)."""
    out = _copy(Lights, lights)
    k = next(k for k in KINDS if k.name == kind)
    data = _copy(k.data, getattr(lights, kind))
    setattr(data, field, alias(getattr(data, field)))
    setattr(out, kind, data)
    return out
