"""Check a render's gradient against finite differences, by parameter name, with standard errors.

:func:`check_gradients` projects each named parameter's gradient (``render_gradients``) on a few
directions and compares each projection with the central difference of the same loss along it,
``(L(x + h d) - L(x - h d)) / 2h``, rendered by the forward renderer (which knows nothing of
gradients). Both sides are estimated over several render seeds, and seed ``s`` of the gradient and
seed ``s`` of the difference are a pair: with the difference's spp equal to the gradient's, the two
trace the same paths (common random numbers), so a colour's gradient and its difference agree to
rounding, seed for seed; and whatever the spp, the standard error of the mean of the pairs'
differences is the error of the comparison (the seeds' pairs are independent).

A row agrees when ``|gradient - difference| <= rtol * max(|gradient|, |difference|) + atol`` or
``<= sigmas * se (+ the truncation bound)`` with that statistical tolerance below ``resolve`` times
the larger of the two (otherwise the row is "unresolved": the noise hides whether they agree);
else it disagrees. A silhouette the step moves makes the difference's error O(h) rather than
O(h^2): ``truncation=True`` also differences with 2h and adds |D(2h) - D(h)| to the tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from warp_spt.diff.geometry_params import MESH, POSE, SPHERE
from warp_spt.diff.gradients import DEFAULT_SETTINGS, render_gradients
from warp_spt.diff.params import ENVIRONMENT, ParamInfo, SceneParameters, value_range
from warp_spt.losses import Loss
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene

COMPONENTS = 4          # a parameter of at most this many numbers is checked along each of them
REL_STEP = 1e-2         # the default step, relative to the parameter's range or size (default_step)
AGREE, DISAGREE, UNRESOLVED = "agree", "DISAGREE", "unresolved"
# keywords of render_gradients that check_gradients sets itself
_OWN = ("wrt", "loss", "adjoint", "gradient_seed")


@dataclass(frozen=True)
class GradientRow:
    """One checked direction: the means over the seeds of the gradient's projection ``gradient`` and
    of the finite difference ``difference``, their standard errors, ``se`` that of their difference
    (over the seeds' pairs), ``z`` = (gradient - difference) / se, ``step`` h, ``scheme``
    "central", "forward" or "backward", ``truncation`` |D(2h) - D(h)| (0 unless asked), ``note``
    what the bounds did to the step, ``verdict`` "agree", "DISAGREE" or "unresolved"."""

    name: str
    direction: str
    gradient: float
    gradient_se: float
    difference: float
    difference_se: float
    se: float
    z: float
    step: float
    scheme: str
    truncation: float
    note: str
    verdict: str

    @property
    def relative(self) -> float:
        """|gradient - difference| / the larger of the two (0 when both are 0)."""
        big = max(abs(self.gradient), abs(self.difference))
        return abs(self.gradient - self.difference) / big if big > 0 else 0.0


@dataclass
class GradientCheck:
    """The rows of :func:`check_gradients`; ``ok``: every row agrees; ``table()`` (and ``str``) the table."""

    rows: list[GradientRow]
    seeds: tuple[int, ...]
    sigmas: float
    rtol: float

    @property
    def ok(self) -> bool:
        return all(r.verdict == AGREE for r in self.rows)

    def rows_of(self, name: str) -> list[GradientRow]:
        return [r for r in self.rows if r.name == name]

    def table(self) -> str:
        head = ("parameter", "direction", "gradient", "finite difference", "z", "rel. diff.", "verdict")
        body = [(r.name, r.direction, f"{r.gradient:.6g} ± {r.gradient_se:.2g}",
                 f"{r.difference:.6g} ± {r.difference_se:.2g}", "-" if not math.isfinite(r.z) else f"{r.z:+.2f}",
                 f"{r.relative:.1e}", r.verdict + (f" ({r.note})" if r.note else "")) for r in self.rows]
        widths = [max(len(x[k]) for x in [head, *body]) for k in range(len(head))]
        lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in [head, *body]]
        lines.insert(1, "  ".join("-" * w for w in widths))
        ok = sum(r.verdict == AGREE for r in self.rows)
        lines.append(f"{ok} of {len(self.rows)} agree ({len(self.seeds)} seeds; z: the difference over its "
                     f"standard error; agree: within {self.sigmas:g} of them, or {self.rtol:g} relative)")
        return "\n".join(lines)

    __str__ = table


def check_gradients(params: SceneParameters, settings: RenderSettings | None = None, *,
                    loss: Loss | None = None, adjoint: np.ndarray | None = None,
                    wrt: Sequence[str] | None = None, seeds: int | Sequence[int] = 4,
                    fd_spp: int | None = None, step: float | Mapping[str, float] | None = None,
                    directions: Mapping[str, np.ndarray] | None = None, random_directions: int = 2,
                    direction_seed: int = 0, sigmas: float = 3.0, rtol: float = 1e-2, atol: float = 0.0,
                    resolve: float = 0.2, truncation: bool = False, print_table: bool = True,
                    **gradient_kwargs) -> GradientCheck:
    """Compare the gradients of ``loss(image)`` (or of sum(adjoint x image)) by the parameters ``wrt``
    (default: all) with finite differences of the render, and return (and print) the table.

    ``seeds``: how many render seeds (``settings.seed``, +1, ...) or which; each gives the gradient
    (``render_gradients`` with ``settings.seed`` = the seed) and the finite difference (two renders
    per direction, at ``fd_spp`` samples per pixel, default ``settings.spp``) of that seed.
    ``step``: h, one for all or by name (default :func:`default_step`); where x +- h d would leave the
    parameter's range (``params.value_range``) the step shrinks to fit (at most 4 times) or the
    difference is one-sided, and the row says so. ``directions``: by name, a direction of the
    parameter's shape or a stack of them (normalised); otherwise a parameter of at most
    ``COMPONENTS`` numbers is checked along each and a bigger one (a mesh's positions, a texture)
    along ``random_directions`` random unit directions drawn from ``direction_seed``.
    ``gradient_kwargs`` go to ``render_gradients`` (``mode``, ``boundary``, ``boundary_spp``,
    ``secondary_spp``, ``secondary_depth``). The parameters hold their values again afterwards, bit
    for bit (``SceneParameters.restored``). Cost: ``len(seeds)`` gradients and 2 ``len(seeds)``
    renders per row (4 with ``truncation``).
    """
    rs = settings or DEFAULT_SETTINGS
    if (loss is None) == (adjoint is None):
        raise ValueError("give exactly one of loss= and adjoint=")
    taken = [k for k in _OWN if k in gradient_kwargs]
    if taken:
        raise TypeError(f"check_gradients sets {', '.join(taken)} itself (seeds= gives the seeds)")
    if isinstance(wrt, str) or not (wrt is None or isinstance(wrt, (list, tuple))):
        raise TypeError(f"wrt must be a list of parameter names (params.names()), got {wrt!r:.80}")
    names = list(params.differentiable() if wrt is None else wrt)
    infos = [params.info(n) for n in names]          # KeyError naming the parameters
    for n in (directions or {}):
        params.info(n)
    seed_list = _seeds(seeds, rs.seed)
    fd_rs = replace(rs, spp=rs.spp if fd_spp is None else fd_spp, features=None)
    if adjoint is not None:
        adjoint = np.asarray(adjoint, np.float64)
        if adjoint.shape != (rs.height, rs.width, 3):
            raise ValueError(f"the adjoint image must have shape {(rs.height, rs.width, 3)}, got {adjoint.shape}")

    def objective(seed: int) -> float:
        film = render_scene(params.scene, params.camera, replace(fd_rs, sky=params.sky, seed=seed)).film
        image = film.sum / film.spp               # float64: the differences lose less to rounding
        return float(np.sum(adjoint * image)) if loss is None else float(loss(image)[0])

    values = {p.name: params[p.name].astype(np.float64) for p in infos}
    plan = [(p, label, d) for p in infos for label, d in _directions(p, values[p.name], directions,
                                                                       random_directions, direction_seed)]
    grads = [render_gradients(params, replace(rs, seed=s), loss=loss, adjoint=adjoint, wrt=names,
                              **gradient_kwargs).grads for s in seed_list]
    rows = []
    with params.restored(names):
        for p, label, d in plan:
            g = np.array([float(np.sum(gs[p.name] * d)) for gs in grads])
            h0 = _step(step, params, p, values[p.name])
            h, scheme, note = _scheme(p, values[p.name], d, h0, 2.0 if truncation else 1.0)
            fd = _differences(params, p.name, values[p.name], d, h, scheme, objective, seed_list)
            trunc = 0.0
            if truncation:
                trunc = abs(float(np.mean(_differences(params, p.name, values[p.name], d, 2 * h, scheme,
                                                       objective, seed_list))) - float(np.mean(fd)))
            rows.append(_row(p.name, label, g, fd, h, scheme, trunc, note, sigmas, rtol, atol, resolve))
    result = GradientCheck(rows, tuple(seed_list), sigmas, rtol)
    if print_table:
        print(result.table())
    return result


def default_step(params: SceneParameters, p: ParamInfo, value: np.ndarray) -> float:
    """The step h of a parameter's finite difference: REL_STEP of its range where it is bounded on
    both sides (colours, roughness, texels, a medium's g: 0.01); of a sphere's radius, or of the
    diagonal of its mesh's box for positions and translations; REL_STEP radians of a rotation, a
    degree of the environment's turn; else REL_STEP of the value's largest magnitude (at least 1)."""
    low, high = value_range(p)
    if low is not None and high is not None and high - low <= 2.0:
        return REL_STEP * (high - low)
    if p.kind == SPHERE:
        return REL_STEP * float(params.scene.scene.spheres[p.index][3])
    if p.kind == MESH or (p.kind == POSE and p.field == "translation"):
        k = p.index if p.kind == MESH else params.pose(p.name).mesh
        pos = np.asarray(params.scene.scene.meshes[k].positions, np.float64)
        return REL_STEP * float(np.linalg.norm(np.ptp(pos, axis=0)))
    if p.kind == POSE and p.field == "rotation":
        return REL_STEP
    if (p.kind, p.field) == (ENVIRONMENT, "rotate"):
        return 1.0
    return REL_STEP * max(1.0, float(np.max(np.abs(value))) if value.size else 1.0)


def _seeds(seeds, first: int) -> list[int]:
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, bool):
        if seeds < 1:
            raise ValueError(f"seeds must be at least 1, got {seeds}")
        return [first + k for k in range(int(seeds))]
    out = [int(s) for s in seeds]
    if not out or len(set(out)) != len(out):
        raise ValueError(f"seeds must be a count or distinct seeds, got {seeds!r}")
    return out


def _step(step, params, p: ParamInfo, value: np.ndarray) -> float:
    h = step.get(p.name) if isinstance(step, Mapping) else step
    h = default_step(params, p, value) if h is None else float(h)
    if not (h > 0 and math.isfinite(h)):
        raise ValueError(f"{p.name}: the step must be a positive number, got {h!r}")
    return h


def _directions(p: ParamInfo, value: np.ndarray, given, count: int, seed: int) -> list[tuple[str, np.ndarray]]:
    """(label, unit direction of the parameter's shape) to check ``p`` along."""
    if given and p.name in given:
        d = np.asarray(given[p.name], np.float64)
        stack = d[None] if d.shape == p.shape else d
        if stack.shape[1:] != p.shape or not len(stack):
            raise ValueError(f"{p.name}: a direction must have the parameter's shape {p.shape} "
                             f"(or be a stack of them), got {d.shape}")
        out = []
        for k, u in enumerate(stack):
            n = float(np.linalg.norm(u))
            if not (n > 0 and math.isfinite(n)):
                raise ValueError(f"{p.name}: direction {k} must be finite and not zero")
            label = "(" + ", ".join(f"{x:g}" for x in u.reshape(-1)) + ")" if u.size <= COMPONENTS else f"given {k}"
            out.append((label, u / n))
        return out
    if value.size <= COMPONENTS:
        out = []
        for k in range(value.size):
            e = np.zeros(value.size)
            e[k] = 1.0
            out.append(("" if p.shape == () else f"[{k}]", e.reshape(p.shape)))
        return out
    rng = np.random.default_rng([seed, *p.name.encode()])      # the same directions whatever else is checked
    out = []
    for k in range(count):
        u = rng.standard_normal(p.shape)
        out.append((f"random {k}", u / np.linalg.norm(u)))
    return out


def _room(p: ParamInfo, x: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """How far x may move along +d and along -d within the parameter's range."""
    low, high = value_range(p)
    if p.kind == SPHERE and p.field == "radius":
        low = 0.0
    up = down = math.inf
    for lim, sign in ((high, 1.0), (low, -1.0)):
        if lim is None:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (lim - x) / d                     # where component i meets the bound
        ahead = t[(d * sign > 0)]                 # moving along +d towards it
        behind = -t[(d * sign < 0)]               # moving along -d towards it
        if ahead.size:
            up = min(up, float(ahead.min()))
        if behind.size:
            down = min(down, float(behind.min()))
    return up, down


def _scheme(p: ParamInfo, x: np.ndarray, d: np.ndarray, h: float, reach: float) -> tuple[float, str, str]:
    """(step, "central" | "forward" | "backward", note): central with ``h`` where x +- reach h d stay
    in range, with a step shrunk to fit down to h / 4, else one-sided towards the room."""
    up, down = _room(p, x, d)
    low, high = value_range(p)
    span = f"[{'-inf' if low is None else f'{low:g}'}, {'inf' if high is None else f'{high:g}'}]"
    if min(up, down) >= reach * h:
        return h, "central", ""
    if min(up, down) >= reach * h / 4:
        s = min(up, down) / reach
        return s, "central", f"h {s:.3g} for {h:.3g}: the range {span}"
    side, room = ("forward", up) if up >= down else ("backward", down)
    s = min(h, room / reach)
    if s <= 0:
        raise ValueError(f"{p.name}: no room to step along this direction within {span}")
    return s, side, f"{side} difference, h {s:.3g}: the range {span}"


def _differences(params, name: str, x: np.ndarray, d: np.ndarray, h: float, scheme: str, objective,
                 seeds: list[int]) -> np.ndarray:
    """The finite difference of each seed (common random numbers on both sides)."""
    out = []
    for s in seeds:
        if scheme == "central":
            params[name] = x + h * d
            a = objective(s)
            params[name] = x - h * d
            b = objective(s)
            out.append((a - b) / (2 * h))
        else:
            sign = 1.0 if scheme == "forward" else -1.0
            params[name] = x + sign * h * d
            a = objective(s)
            params[name] = x
            b = objective(s)
            out.append(sign * (a - b) / h)
    params[name] = x            # the next row's differences are taken at x
    return np.array(out)


def _row(name, label, g, fd, h, scheme, trunc, note, sigmas, rtol, atol, resolve) -> GradientRow:
    n = len(g)

    def se(v):
        return float(np.std(v, ddof=1) / math.sqrt(n)) if n > 1 else 0.0

    mg, mf, s = float(np.mean(g)), float(np.mean(fd)), se(g - fd)
    gap = abs(mg - mf)
    big = max(abs(mg), abs(mf))
    stat = sigmas * s + trunc
    if gap <= rtol * big + atol:
        verdict = AGREE
    elif gap <= stat:
        verdict = AGREE if stat <= resolve * big else UNRESOLVED
    else:
        verdict = DISAGREE
    z = (mg - mf) / s if s > 0 else (0.0 if gap == 0 else math.inf)
    return GradientRow(name, label, mg, se(g), mf, se(fd), s, z, h, scheme, trunc, note, verdict)
