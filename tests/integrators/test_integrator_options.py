"""Integrator parameters by name (issue 24): ``Integrator.params``, ``RenderSettings.integrator_options``.

* Validation: an unknown option, an ill-typed value or one out of range is a ValueError naming the
  option and what it allows (or the integrator's options), raised by the settings' check before
  anything is uploaded; every declared default passes its own check; no integrator keeps a
  module-level switch.
* Effect: ``guided`` with ``alpha`` 0 is ``nee``'s estimator, its image ``nee``'s bit for bit;
  ``ears`` whose ``train_fraction`` leaves fewer than two training samples is ``nee``.
* The command line: ``--integrator-option NAME=VALUE`` reaches the settings, typed by the
  parameter; a bad one is a one-line usage error (exit status 2).
"""

from __future__ import annotations

import pickle
import re

import numpy as np
import pytest

from warp_spt.integrators import INTEGRATORS, describe_options, ears, get_integrator, guided
from warp_spt.rendering.settings import RenderSettings, check_args

from tests.support.stability_scenes import R, cornell_camera, cornell_files, load, sky


def _check(integrator: str, **options) -> None:
    check_args(RenderSettings(integrator=integrator, integrator_options=options))


@pytest.mark.parametrize("integrator, options, words", [
    ("guided", {"beta": 0.1}, ["unknown option 'beta'", "'guided'", "alpha", "stop_fraction"]),
    ("nee", {"alpha": 0.1}, ["integrator 'nee' takes no options", "'alpha'"]),
    ("guided", {"alpha": "0.5"}, ["'alpha'", "float in [0, 1) or None", "'0.5'"]),
    ("guided", {"alpha": True}, ["'alpha'", "float"]),
    ("guided", {"stop_after": 2.0}, ["'stop_after'", "int in [1, 32]"]),
    ("ears", {"relative": 1}, ["'relative'", "bool"]),
    ("guided", {"alpha": 1.0}, ["'alpha'", "[0, 1)", "1.0"]),
    ("guided", {"alpha": -0.1}, ["'alpha'"]),
    ("guided", {"stop_after": None}, ["'stop_after'", "int in [1, 32]"]),
    ("guided", {"rho": 0.0}, ["'rho'", "[0.001, 1]"]),
    ("guided", {"guide_cost": float("inf")}, ["'guide_cost'"]),
    ("guided", {"stop_fraction": float("nan")}, ["'stop_fraction'"]),
    ("ears", {"q_min": 0.0}, ["'q_min'", "(0, 1]"]),
    ("ears", {"grid": 65}, ["'grid'", "int in [1, 64]"]),
])
def test_bad_options_are_refused_naming_the_option(integrator, options, words):
    with pytest.raises(ValueError) as err:
        _check(integrator, **options)
    for w in words:
        assert w in str(err.value)


def test_options_must_be_a_mapping_and_reach_no_kernel():
    with pytest.raises(ValueError, match="integrator_options must be a dict"):
        check_args(RenderSettings(integrator="guided", integrator_options=[("alpha", 0.1)]))
    # the settings are checked before the scene is even looked at: nothing is uploaded
    with pytest.raises(ValueError, match="'alpha'"):
        R.render_scene(None, None, RenderSettings(integrator="guided", integrator_options={"alpha": 2}))


def test_good_options_are_normalised_and_defaults_fill_the_rest():
    rec = get_integrator("guided")
    opts = rec.options({"alpha": np.float32(0.25), "stop_after": np.int64(3), "guide_cost": 1})
    assert opts["alpha"] == 0.25 and type(opts["alpha"]) is float
    assert opts["stop_after"] == 3 and type(opts["stop_after"]) is int
    assert opts["guide_cost"] == 1.0 and type(opts["guide_cost"]) is float
    assert opts["stop_fraction"] == rec.defaults()["stop_fraction"]
    assert set(opts) == {p.name for p in rec.params}
    assert rec.options({"alpha": None})["alpha"] is None
    assert get_integrator("ears").options({"relative": np.bool_(True)})["relative"] is True
    # settings with options compare and pickle (the cluster ships settings)
    rs = RenderSettings(integrator="guided", integrator_options={"alpha": 0.5})
    assert pickle.loads(pickle.dumps(rs)) == rs


def test_every_default_passes_its_own_check_and_no_module_switch_is_left():
    for name, rec in INTEGRATORS.items():
        assert rec.options() == rec.defaults()
        assert len({p.name for p in rec.params}) == len(rec.params)
        assert describe_options(name).startswith(name)
    assert get_integrator("guided").params and get_integrator("ears").params
    for module, switches in ((guided, ("ALPHA", "STOP_AFTER", "STOP_FRACTION", "MAX_RECORDS")),
                             (ears, ("RELATIVE", "Q_MIN", "Q_MAX", "GRID", "TRAIN_FRACTION", "STACK"))):
        assert not [s for s in switches if hasattr(module, s)]


def test_parse_types_the_command_lines_text():
    rec = get_integrator("guided")
    assert rec.parse_options([("alpha", "none"), ("stop_after", "3"), ("rho", "0.05")]) == {
        "alpha": None, "stop_after": 3, "rho": 0.05}
    assert get_integrator("ears").parse_options([("relative", "true")]) == {"relative": True}
    for pair, words in ((("stop_after", "2.5"), "int in [1, 32]"), (("alpha", "nan"), "'nan'"),
                        (("alpha", "2"), "got '2'"), (("relative", "maybe"), "true or false")):
        with pytest.raises(ValueError, match=re.escape(words)):
            (get_integrator("ears") if pair[0] == "relative" else rec).parse_options([pair])


# --------------------------------------------------------------------------------------------
# What the options do


@pytest.fixture(scope="module")
def cornell(scene_dir):
    return load(*cornell_files(scene_dir))


def _film(dev, integrator: str, spp: int, **options) -> np.ndarray:
    rs = RenderSettings(width=16, height=16, spp=spp, max_depth=5, sky=sky(0.3), threads=1, integrator=integrator,
                        integrator_options=options)
    return R.render_scene(dev, cornell_camera(), rs).film.sum


def test_guided_with_alpha_0_is_nee_bit_for_bit(cornell):
    # alpha 0: every vertex samples the material alone and weighs light sampling with (1 - 0) p_material,
    # nee's estimator and dimensions; the training passes only record (guided.py's docstring)
    for spp in (2, 12):
        assert np.array_equal(_film(cornell, "guided", spp, alpha=0.0), _film(cornell, "nee", spp))
    assert not np.array_equal(_film(cornell, "guided", 12, alpha=0.5), _film(cornell, "nee", 12))


def test_ears_train_fraction_sets_its_training(cornell):
    # 16 spp trains on 4 by default (then decides: not nee's image); with train_fraction 16 on 1,
    # fewer than two: nothing is learnt, nee's image
    assert ears.schedule(16, {"train_fraction": 16}) == (0, 0, 16)
    assert np.array_equal(_film(cornell, "ears", 16, train_fraction=16), _film(cornell, "nee", 16))


# --------------------------------------------------------------------------------------------
# The command line


def test_cli_integrator_option_reaches_the_settings():
    from warp_spt.cli.options import parse_args, settings_of

    opts = parse_args(["--integrator", "guided", "--integrator-option", "alpha=0.25",
                       "--integrator-option", "stop_after = 3"])
    assert opts.integrator_options == (("alpha", "0.25"), ("stop_after", "3"))
    assert settings_of(opts).integrator_options == {"alpha": 0.25, "stop_after": 3}
    assert settings_of(parse_args([])).integrator_options == {}


@pytest.mark.parametrize("args, words", [
    (["--integrator", "guided", "--integrator-option", "alpha=2"], "'alpha' of integrator 'guided' must be"),
    (["--integrator", "guided", "--integrator-option", "beta=2"], "its options: alpha"),
    (["--integrator-option", "alpha=0.1"], "integrator 'nee' takes no options"),
    (["--integrator", "guided", "--integrator-option", "alpha"], "expected NAME=VALUE"),
    (["--integrator", "guided", "--integrator-option", "alpha=0.1", "--integrator-option", "alpha=0.2"],
     "given more than once"),
])
def test_cli_bad_integrator_option_is_one_line(tmp_path, capsys, args, words):
    from warp_spt.cli.main import main as cli_main

    status = cli_main(["-res", "8", "8", "-sr", "1", "-out", str(tmp_path / "o.png"), *args])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and words in err and "internal error" not in err
    assert not (tmp_path / "o.png").exists()
