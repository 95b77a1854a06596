"""The README's examples run as written (issues 10, 22 and 43), and --help says which axis is up.

Every fenced ``python`` block runs as a script from an empty folder; a block after a marker comment
(``<!-- tested: NAME -->``, invisible on GitHub) is also run here in-process with checks on what it
made, so a test cannot silently run some other block. Every ``warp-spt`` line of a ``bash`` block
parses (its flags exist and take their values): those lines name the user's own files, so they are
not run. A failure names the block's line in README.md, and a traceback's line numbers are README's.
"""

from __future__ import annotations

import math
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest

from warp_spt.cli.common import UsageError
from warp_spt.cli.options import build_parser, parse_args

from tests.conftest import REPO

# What a block needs beyond the base install: a module it imports, and the extra that brings it.
EXTRAS = {"warp_spt.cluster": "dask.distributed", "from warp_spt import cluster": "dask.distributed",
          "pyoidn": "pyoidn"}


@dataclass(frozen=True)
class Block:
    lang: str
    line: int           # README.md's line of the block's first line of code
    code: str
    marker: str | None  # the ``tested:`` name on the line before the fence

    def padded(self) -> str:
        """The code preceded by blank lines, so that compiled line numbers are README.md's."""
        return "\n" * (self.line - 1) + self.code


def readme_blocks() -> list[Block]:
    lines = (REPO / "README.md").read_text(encoding="utf-8").splitlines()
    blocks, i = [], 0
    while i < len(lines):
        if lines[i].startswith("```"):
            j = next(k for k in range(i + 1, len(lines)) if lines[k].startswith("```"))
            found = re.fullmatch(r"<!-- tested: (\w+) -->", lines[i - 1].strip()) if i else None
            blocks.append(Block(lines[i][3:].strip(), i + 2, "\n".join(lines[i + 1:j]) + "\n",
                                found.group(1) if found else None))
            i = j
        i += 1
    return blocks


def readme_block(name: str) -> Block:
    """The ```python block after the README's ``<!-- tested: NAME -->`` marker."""
    found = [b for b in readme_blocks() if b.marker == name]
    assert len(found) == 1 and found[0].lang == "python", f"README.md should hold one python block tested: {name}"
    return found[0]


def _run_in(block: Block, names: dict) -> None:
    """Run as a script would be, in the current folder."""
    names.setdefault("__name__", "__main__")
    exec(compile(block.padded(), str(REPO / "README.md"), "exec"), names)


# The blocks that the tests below run in-process, with checks on what they made (and the kernels warm)
IN_PROCESS = ("api", "gradients")
PYTHON = [b for b in readme_blocks() if b.lang == "python" and b.marker not in IN_PROCESS]


@pytest.mark.parametrize("block", PYTHON, ids=[b.marker or f"line{b.line}" for b in PYTHON])
def test_every_python_block_runs_as_a_script_from_an_empty_folder(block, tmp_path):
    """In a process of its own (the cluster block's workers import the script), the extras it
    needs skipped cleanly where absent."""
    for needle, module in EXTRAS.items():
        if needle in block.code:
            pytest.importorskip(module, reason=f"README.md line {block.line} needs {module}")
    script = tmp_path / "snippet.py"
    script.write_text(block.padded())
    env = dict(os.environ, PYTHONPATH=str(REPO))       # Warp's kernel cache stays the suite's (warm)
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, f"README.md line {block.line}: the block fails as a script\n{done.stderr[-3000:]}"


def test_every_warp_spt_command_in_a_bash_block_parses():
    from warp_spt.cli.view import build_parser as view_parser
    from warp_spt.cli.convergence import _parser as convergence_parser

    commands = 0
    for block in (b for b in readme_blocks() if b.lang == "bash"):
        text = block.code.replace("\\\n", " \n")     # a continued line is one command
        for k, line in enumerate(text.splitlines()):
            for command in line.split("&&"):
                words = shlex.split(command, comments=True)
                if not words or words[0] != "warp-spt":
                    continue
                commands += 1
                where = f"README.md line {block.line + k}: {' '.join(words)}"
                try:
                    if words[1:2] == ["view"]:
                        view_parser().parse_args(words[2:])
                    elif words[1:2] == ["convergence"]:
                        _, rest = convergence_parser().parse_known_args(words[2:])   # as its main does
                        parse_args(rest)
                    else:
                        assert parse_args(words[1:]).action == "render", where
                except (SystemExit, UsageError) as err:     # argparse exits; parse_args raises UsageError
                    pytest.fail(f"{where}: does not parse ({err})")
    assert commands >= 10, commands


def test_every_python_block_is_run_by_a_test():
    names = {b.marker for b in readme_blocks() if b.marker}
    assert set(IN_PROCESS) <= names, f"README.md lost a tested block: {set(IN_PROCESS) - names}"
    assert all(b.lang == "python" for b in readme_blocks() if b.marker)


def test_the_readme_api_example_runs_as_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    _run_in(readme_block("api"), names)
    assert (tmp_path / "out.png").stat().st_size > 0
    # the framed vase fills a sensible share of its image (the sky is the seed's constant blue)
    sky = np.array([0.3, 0.6, 0.8], dtype=np.float32)
    assert 0.05 < float((np.abs(names["img"] - sky).max(axis=2) > 1e-6).mean()) < 0.9


def test_the_readme_gradients_example_runs_as_written(tmp_path, monkeypatch, capsys):
    """The Gradients section's block, with its own (small) settings: the loss and the gradients it
    prints are finite and not zero, and the red wall's gradient points back to its true colour."""
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    _run_in(readme_block("gradients"), names)
    printed = [float(x) for x in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|nan|inf", capsys.readouterr().out)]
    res = names["res"]
    assert len(printed) >= 5 and all(math.isfinite(x) for x in printed), printed
    assert math.isfinite(res.loss) and res.loss > 0
    for name, grad in res.grads.items():
        assert np.all(np.isfinite(grad)) and np.abs(grad).max() > 1e-6, (name, grad)
    red = res.grads["red.diffuse"]      # the wall was set to grey: more red, less green and blue
    assert red[0] < 0 < min(red[1], red[2]), red


def test_help_says_which_axis_is_up_and_how_to_change_it():
    text = " ".join(build_parser().format_help().split())
    assert "keep the seed's Z up" in text and "any other model is Y up" in text and "--up wins" in text
