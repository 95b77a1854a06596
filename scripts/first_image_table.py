"""The first image of each generated model (tests/support/first_image.py), before and after: a Markdown table.

Runs ``python -m warp_spt -obj MODEL`` with no other flag (a new user's first command) from two
source trees and judges each image with this tree's checks (upright, in frame, lit)::

    mkdir /tmp/before31 && git archive 0e4d3a5 | tar -x -C /tmp/before31
    python scripts/first_image_table.py --before /tmp/before31

Each tree's own camera is judged: the one it printed when it framed the scene, else the seed's. A
model on a ground is judged on what stands on the ground. "studio" says whether the command said it
added the studio look; "smooth" whether the model it rendered had shading normals (issue 31).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.first_image import MODELS, SIZE, judge, write_case  # noqa: E402


def render(tree: Path, obj: str, out: Path) -> tuple[np.ndarray, str]:
    cmd = [sys.executable, "-m", "warp_spt", "-obj", obj, "-res", str(SIZE[0]), str(SIZE[1]), "-sr", "16",
           "-out", str(out)]
    done = subprocess.run(cmd, env={**os.environ, "PYTHONPATH": str(tree)}, capture_output=True, text=True, cwd=out.parent,
                          check=True)
    return np.load(out), done.stderr


def smooth_normals_of(obj: str) -> str:
    """Whether the command line's loader gives the model shading normals (this tree's rule)."""
    from warp_spt.io.loader import load_scene

    scene = load_scene([obj], warn=lambda m: None, default_material="auto", smooth_angle="auto")
    return "yes" if all(m.corner_normal is not None for m in scene.meshes) else "no"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True, help="source tree of the commit before")
    ap.add_argument("--after", type=Path, default=ROOT, help="source tree after (default: this one)")
    args = ap.parse_args()
    print("| model | before: upright | in frame | lit | studio | after: upright | in frame | lit | studio | smooth "
          "| up assumed |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in MODELS:
            folder = Path(tmp) / str(abs(hash(name)))
            folder.mkdir()
            obj, _ = write_case(folder, name)            # the case's flags are left out: a first command
            cells = []
            for tree in (args.before, args.after):
                image, said = render(tree, obj, folder / "first.npy")
                v = judge(obj, MODELS[name][1], image, said, "z", base="base" in MODELS[name][4])
                cells.append(f"{v.row()} | {'yes' if 'studio look' in said else 'no'}")
            smooth = smooth_normals_of(obj)
            print(f"| {name.replace(', --up z', ', no flags')} | {cells[0]} | {cells[1]} | {smooth} | {v.up} |")


if __name__ == "__main__":
    main()
