"""One default sampler for every front end (issue 43, item 8): the viewer's settings, the command line
it copies, RenderSettings and the command line itself all take ``scene.families.DEFAULT_SAMPLER``
(before, the viewer rendered and copied ``--sampler sobol`` where the command line's default is
``sobol-affine``)."""

from __future__ import annotations

from warp_spt.cli.options import parse_args, settings_of
from warp_spt.rendering.settings import RenderSettings
from warp_spt.samplers import DEFAULT_SAMPLER, SAMPLERS
from warp_spt.scene.camera import Camera
from warp_spt.scene.families import DEFAULT_SAMPLER as NAMED
from warp_spt.viewer.command import CommandSpec, command_args
from warp_spt.viewer.session import ViewSettings


def test_the_viewer_and_the_command_line_share_one_default_sampler():
    assert DEFAULT_SAMPLER is NAMED and DEFAULT_SAMPLER in SAMPLERS
    cli = settings_of(parse_args(["-obj", "a.obj"])).sampler
    assert ViewSettings().sampler == CommandSpec().sampler == RenderSettings().sampler == cli == DEFAULT_SAMPLER
    # the command the viewer copies, read back by the command line, renders with the viewer's sampler
    args = command_args(Camera(), CommandSpec(objs=("a.obj",)))
    assert settings_of(parse_args(args[1:])).sampler == ViewSettings().sampler
