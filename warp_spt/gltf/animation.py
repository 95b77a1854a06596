"""Animation: the first animation's channels (translation, rotation, scale, morph weights) and glTF's
keyframe interpolation, sampled at the time asked."""

from __future__ import annotations

import math

import numpy as np

from warp_spt.gltf.document import _err
from warp_spt.gltf.meshes import Meshes


class Animation(Meshes):
    def _animation(self, n_nodes: int) -> tuple[dict[int, dict], tuple[float, float] | None]:
        """The first animation's channels as {node: {path: sampler(time)}} and its time range.
        Morph target weights are not animated (a warning); other animations are not played."""
        animations = self.get(self.doc, "animations", list, "", [])
        if not animations:
            return {}, None
        if len(animations) > 1:
            self.warnings.append(f"{self.path}: {len(animations)} animations; the first is played")
        ptr = "/animations/0"
        anim = self.item("animations", 0)
        samplers = self.get(anim, "samplers", list, ptr, required=True)
        out: dict[int, dict] = {}
        lo, hi = math.inf, -math.inf
        for c, channel in enumerate(self.get(anim, "channels", list, ptr, required=True)):
            cptr = f"{ptr}/channels/{c}"
            if not isinstance(channel, dict):
                raise _err(self.path, cptr, "expected an object")
            target = self.obj(channel, "target", cptr, required=True)
            path = self.get(target, "path", str, f"{cptr}/target", required=True)
            node = self.get(target, "node", int, f"{cptr}/target")
            if node is None:
                continue                    # an extension's target: nothing to animate here
            if not 0 <= node < n_nodes:
                raise _err(self.path, f"{cptr}/target/node", f"node index {node} is out of range: the file has "
                           f"{n_nodes} nodes")
            if path not in ("translation", "rotation", "scale", "weights"):
                raise _err(self.path, f"{cptr}/target/path", f"expected translation, rotation, scale or weights, "
                           f"got {path!r}")
            k = self.get(channel, "sampler", int, cptr, required=True)
            if not 0 <= k < len(samplers) or not isinstance(samplers[k], dict):
                raise _err(self.path, f"{cptr}/sampler", f"sampler index {k} is out of range: the animation has "
                           f"{len(samplers)} samplers")
            targets = self._targets_of_node(node) if path == "weights" else 0
            if path == "weights" and targets == 0:
                raise _err(self.path, f"{cptr}/target", f"node {node} has no mesh with morph targets to weigh")
            times, values, interpolation = self._sampler(samplers[k], f"{ptr}/samplers/{k}", path, targets)
            lo, hi = min(lo, float(times[0])), max(hi, float(times[-1]))
            out.setdefault(node, {})[path] = _channel(times, values, interpolation, path == "rotation")
        return out, ((lo, hi) if lo <= hi else None)

    def _sampler(self, sampler: dict, ptr: str, path: str, targets: int = 0):
        interpolation = self.get(sampler, "interpolation", str, ptr, "LINEAR")
        if interpolation not in ("LINEAR", "STEP", "CUBICSPLINE"):
            raise _err(self.path, f"{ptr}/interpolation", f"expected LINEAR, STEP or CUBICSPLINE, got {interpolation!r}")
        k_in = self.index(sampler, "input", ptr, "accessors", required=True)
        times = self.accessor(k_in, widths=("SCALAR",)).reshape(-1)
        if self.item("accessors", k_in).get("componentType") != 5126:
            raise _err(self.path, f"/accessors/{k_in}", "animation times must be float (5126) scalars")
        if np.any(np.diff(times) <= 0) or times[0] < 0:
            raise _err(self.path, f"/accessors/{k_in}", "animation times must be >= 0 and increase strictly")
        k_out = self.index(sampler, "output", ptr, "accessors", required=True)
        values = self.accessor(k_out, widths=("VEC4",) if path == "rotation" else ("SCALAR",) if path == "weights"
                               else ("VEC3",))
        per_key = 3 if interpolation == "CUBICSPLINE" else 1
        if path == "weights":           # one value per target and key: rows of the targets' weights
            values = np.asarray(values, np.float64).reshape(-1)
            if len(values) != per_key * len(times) * targets:
                raise _err(self.path, f"/accessors/{k_out}", f"{len(values)} weights for {len(times)} key times "
                           f"and {targets} morph targets; {interpolation} needs {per_key * len(times) * targets}")
            return times, values.reshape(per_key * len(times), targets), interpolation
        if len(values) != per_key * len(times):
            raise _err(self.path, f"/accessors/{k_out}", f"{len(values)} output values for {len(times)} key times; "
                       f"{interpolation} needs {per_key * len(times)}")
        return times, values, interpolation


def _channel(times: np.ndarray, values: np.ndarray, interpolation: str, rotation: bool):
    """A function of time giving the channel's value: clamped outside the key times."""
    return lambda t: sample_channel(times, values, interpolation, t, rotation)


def sample_channel(times: np.ndarray, values: np.ndarray, interpolation: str, t: float,
                   rotation: bool = False) -> list[float]:
    """glTF's keyframe interpolation at time ``t`` (seconds; clamped to the key times): STEP holds the
    previous key, LINEAR blends (rotations: spherical, along the shorter arc), CUBICSPLINE is the
    Hermite spline of the (in-tangent, value, out-tangent) triples with tangents scaled by the key
    interval; rotations are normalised."""
    cubic = interpolation == "CUBICSPLINE"
    keys = values.reshape(len(times), 3, -1)[:, 1] if cubic else values
    if t <= times[0] or len(times) == 1:
        out = keys[0]
    elif t >= times[-1]:
        out = keys[-1]
    else:
        k = int(np.searchsorted(times, t, side="right")) - 1
        t0, t1 = float(times[k]), float(times[k + 1])
        dt = t1 - t0
        u = (t - t0) / dt
        if interpolation == "STEP":
            out = keys[k]
        elif cubic:
            v = values.reshape(len(times), 3, -1)
            u2, u3 = u * u, u * u * u
            out = ((2 * u3 - 3 * u2 + 1) * v[k, 1] + (u3 - 2 * u2 + u) * dt * v[k, 2]
                   + (-2 * u3 + 3 * u2) * v[k + 1, 1] + (u3 - u2) * dt * v[k + 1, 0])
        elif rotation:
            out = slerp(keys[k], keys[k + 1], u)
        else:
            out = (1 - u) * keys[k] + u * keys[k + 1]
    out = np.asarray(out, np.float64)
    if rotation:
        norm = np.linalg.norm(out)
        out = out / norm if norm > 0 else np.array([0.0, 0.0, 0.0, 1.0])
    return [float(c) for c in out]


def slerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    """Spherical interpolation of unit quaternions along the shorter arc."""
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if not (na > 0 and nb > 0):         # a zero key: no rotation to blend from or to
        return np.asarray(a if na > 0 else b if nb > 0 else [0.0, 0.0, 0.0, 1.0], np.float64)
    a = np.asarray(a, np.float64) / na
    b = np.asarray(b, np.float64) / nb
    dot = float(np.dot(a, b))
    if dot < 0:
        b, dot = -b, -dot
    if dot > 0.9995:                     # nearly equal: the chord is the arc
        out = a + u * (b - a)
        return out / np.linalg.norm(out)
    theta = math.acos(dot)
    return (math.sin((1 - u) * theta) * a + math.sin(u * theta) * b) / math.sin(theta)
