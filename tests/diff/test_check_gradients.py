"""warp_spt.check_gradients: it agrees where the gradient is right, flags a wrong one, restores the
parameters bit for bit and prints one row per checked direction.

The references are its own finite differences of the forward renderer, so the checks that it
agrees are checks of render_gradients too; the checks that it disagrees use gradients known to be
wrong (the silhouette term left out, a gradient scaled by 5%). The scenes are other files' whose
kernels the default tier compiles already: the room of test_gradients.py at ROOM_RS (the fast,
replay, pathwise and boundary kernels of test_param_gradients.py) and the textured quad of
test_camera_sky_proctex_gradients.py (its silhouette test's): no kernel of its own.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import warp_spt
from warp_spt import losses
from warp_spt.diff import check as C
from warp_spt.diff.params import parameters
from warp_spt.rendering.tiles import render_scene

from tests.diff.test_camera_sky_proctex_gradients import CAM as QUAD_CAM
from tests.diff.test_camera_sky_proctex_gradients import RS as QUAD_RS
from tests.diff.test_camera_sky_proctex_gradients import SKY as QUAD_SKY
from tests.diff.test_camera_sky_proctex_gradients import noise_quad
from tests.diff.test_gradients import room  # noqa: F401  (fixture)
from tests.diff.test_param_gradients import ROOM_CAM, ROOM_RS, ROOM_SKY

ONES = np.ones((ROOM_RS.height, ROOM_RS.width, 3))


def _film(p) -> np.ndarray:
    return render_scene(p.scene, p.camera, replace(ROOM_RS, sky=p.sky)).film.sum


def test_colour_gradients_agree_and_the_table_has_a_row_per_direction(room, capsys):
    """Colours and emission: with common random numbers (seed s on both sides) the image is a
    polynomial in them and gradient and difference agree seed for seed, to rounding."""
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    target = np.full((ROOM_RS.height, ROOM_RS.width, 3), 0.3)
    r = warp_spt.check_gradients(p, ROOM_RS, loss=losses.l2(target), wrt=["wall.diffuse", "lamp.emission"], seeds=2)
    out = capsys.readouterr().out
    print(out)
    assert [(x.name, x.direction) for x in r.rows] == [(n, f"[{c}]") for n in ("wall.diffuse", "lamp.emission")
                                                       for c in range(3)]
    assert r.ok and all(x.verdict == "agree" and x.scheme == "central" for x in r.rows)
    assert all(abs(x.gradient) > 1e-4 for x in r.rows)          # not vacuous
    # to rounding: far inside the 1% the verdict allows
    assert all(abs(x.gradient - x.difference) < 1e-3 * abs(x.difference) for x in r.rows), out
    lines = out.strip().splitlines()
    assert lines[0].split()[:2] == ["parameter", "direction"] and set(lines[1]) <= {"-", " "}
    body = lines[2:-1]
    assert len(body) == len(r.rows) == 6 and all(x.name in line for x, line in zip(r.rows, body))
    assert lines[-1].startswith("6 of 6 agree") and str(r) == out.strip()


def test_a_gradient_five_percent_off_is_flagged(room, monkeypatch):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    real = C.render_gradients

    def scaled(*a, **kw):
        r = real(*a, **kw)
        r.grads = {n: 1.05 * g for n, g in r.grads.items()}
        return r

    monkeypatch.setattr(C, "render_gradients", scaled)
    r = warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=["lamp.emission"], seeds=2, print_table=False)
    # the pairs' differences are 5% of each seed's gradient: z is the gradient over its standard error
    assert not r.ok and [x.verdict for x in r.rows] == ["DISAGREE"] * 3
    assert all(abs(x.z) > 10 for x in r.rows)


def test_a_quad_translated_agrees_with_the_boundary_term_and_not_without(scene_dir):
    """The textured quad of the camera's silhouette test, seen whole against the gradient sky, moved
    in its plane: the hit points along fixed rays stay where they were (the interior term is 0), the
    outline moves (the boundary term is all of it). With the term the check agrees, within 3
    standard errors resolved to a fifth of the derivative (and with its truncation bound added);
    without it, it disagrees."""
    p = parameters(noise_quad(scene_dir / "checkquad", 0.5), QUAD_CAM, QUAD_SKY)
    name = "noisequad0.5.obj.translation"
    before = p[name]
    kw = dict(adjoint=np.ones((QUAD_RS.height, QUAD_RS.width, 3)), wrt=[name], directions={name: (1.0, 0.5, 0.0)},
              seeds=4, fd_spp=1024, rtol=0.0, print_table=False)
    rs = replace(QUAD_RS, spp=256)
    (row,) = warp_spt.check_gradients(p, rs, **kw).rows
    print(row)
    assert row.verdict == "agree" and abs(row.difference) > 1.0, row
    # with the truncation bound |D(2h) - D(h)| (the outline crosses pixels' sample points: O(h))
    (wide,) = warp_spt.check_gradients(p, rs, truncation=True, **kw).rows
    assert wide.difference == row.difference and wide.truncation > 0 and wide.verdict == "agree", wide
    interior = warp_spt.check_gradients(p, rs, boundary=False, **kw)
    (row0,) = interior.rows
    assert row0.verdict == "DISAGREE" and row0.gradient == 0 and not interior.ok, row0
    assert row0.difference == row.difference            # the same renders: the same differences
    assert np.array_equal(p[name], before)


def test_values_are_restored_bit_for_bit(room):
    """Materials, the sky (its float64 colours), a sphere, a pose and the camera: the same values, objects
    and film after the check as before it."""
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    names = ["wall.diffuse", "sky.color", "sphere0.radius", "room.obj.rotation", "camera.position"]
    values = {n: p[n] for n in names}
    sky, camera, spheres, film = p.sky, p.camera, p.scene.scene.spheres.copy(), _film(p)
    warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=names, seeds=1, print_table=False)
    for n in names:
        assert np.array_equal(p[n], values[n]), n
    assert p.sky is sky and p.camera is camera and p.sky.color == (0.4, 0.5, 0.6)
    assert np.array_equal(p.scene.scene.spheres, spheres)
    assert np.array_equal(_film(p), film)


def test_bad_names_and_arguments_are_refused_before_anything_renders(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    with pytest.raises(KeyError, match=r"no parameter 'wall\.colour'; parameters are: .*wall\.diffuse"):
        warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=["wall.colour"])
    with pytest.raises(KeyError, match="parameters are"):
        warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=["wall.diffuse"], directions={"nope": (1, 0, 0)})
    with pytest.raises(ValueError, match="exactly one of loss= and adjoint="):
        warp_spt.check_gradients(p, ROOM_RS, wrt=["wall.diffuse"])
    with pytest.raises(TypeError, match="gradient_seed"):
        warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=["wall.diffuse"], gradient_seed=3)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=["wall.diffuse"], directions={"wall.diffuse": (1, 0)})
    with pytest.raises(ValueError, match="seeds"):
        warp_spt.check_gradients(p, ROOM_RS, adjoint=ONES, wrt=["wall.diffuse"], seeds=[1, 1])


def test_steps_shrink_or_turn_one_sided_at_the_bounds(room):
    """A roughness of 1 (the ball's) steps back only; a colour 0.004 below 1 shrinks its step; a
    free one keeps the default (0.01 of [0, 1])."""
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    info = p.info("ball.roughness")
    h = C.default_step(p, info, np.array(1.0))
    assert h == pytest.approx(0.01)
    assert C._scheme(info, np.array(1.0), np.array(1.0), h, 1.0)[:2] == (h, "backward")
    s, scheme, note = C._scheme(p.info("wall.diffuse"), np.array([0.996, 0.5, 0.5]), np.array([1.0, 0, 0]), h, 1.0)
    assert scheme == "central" and s == pytest.approx(0.004) and "[0, 1]" in note
    free = C._scheme(p.info("wall.diffuse"), np.array([0.5, 0.5, 0.5]), np.array([0, 1.0, 0]), h, 1.0)
    assert free == (h, "central", "")
    assert C.default_step(p, p.info("sphere0.radius"), np.array(0.5)) == pytest.approx(0.005)


def test_big_parameters_take_seeded_random_unit_directions(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    info = p.info("room.obj.positions")
    x = p["room.obj.positions"].astype(np.float64)
    a, b = C._directions(info, x, None, 3, 0), C._directions(info, x, None, 3, 0)
    assert [label for label, _ in a] == ["random 0", "random 1", "random 2"]
    for (_, u), (_, v) in zip(a, b):
        assert u.shape == x.shape and np.linalg.norm(u) == pytest.approx(1.0) and np.array_equal(u, v)
    assert not np.array_equal(a[0][1], C._directions(info, x, None, 1, 1)[0][1])      # direction_seed
    assert [label for label, _ in C._directions(p.info("sphere0.radius"), np.array(0.5), None, 3, 0)] == [""]
