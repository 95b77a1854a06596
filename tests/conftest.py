"""Shared test fixtures: scene-file writers and the seed's data (skipped when ../shared is absent)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("WARP_SPT_SHARED", REPO.parent / "shared"))   # a worktree may point elsewhere
SEED_DEMO = SHARED / "seed" / "demo"

os.environ.setdefault("WARP_SPT_QUIET", "1")


def pytest_configure(config):
    """A run started in the background (``nohup pytest &``, a script's ``&``) inherits an ignored
    SIGINT, and so would every process it starts: the tests of Ctrl-C need the disposition a terminal
    gives. A Python handler here also means SIG_DFL in every child the tests start (exec resets
    handled signals, not ignored ones)."""
    import signal

    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def seed_demo() -> Path:
    """The seed's demo folder; the test is skipped where ../shared is not beside the repo."""
    if not (SEED_DEMO / "cornell_export.obj").is_file():
        pytest.skip("../shared/seed/demo is absent (a user's clone has no shared/)")
    return SEED_DEMO


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("scenes")
