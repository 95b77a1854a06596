"""The README's Python API example runs as written (issue 10), and --help says which axis is up."""

from __future__ import annotations

import re

import numpy as np

from warp_spt.cli.options import build_parser

from .conftest import REPO


def api_example() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Python API"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_api_example_runs_as_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    exec(compile(api_example(), "README.md", "exec"), names)
    assert (tmp_path / "out.png").stat().st_size > 0
    # the framed vase fills a sensible share of its image (the sky is the seed's constant blue)
    sky = np.array([0.3, 0.6, 0.8], dtype=np.float32)
    assert 0.05 < float((np.abs(names["img"] - sky).max(axis=2) > 1e-6).mean()) < 0.9


def test_help_says_which_axis_is_up_and_how_to_change_it():
    text = " ".join(build_parser().format_help().split())
    assert "keep the seed's Z up" in text and "any other model is Y up" in text and "--up wins" in text
