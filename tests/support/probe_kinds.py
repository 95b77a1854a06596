"""Register probe kinds of a plugin family the way a new kind is registered: its module (written to a
file, for Warp reads a function's source) and its name in the family's one list,
``warp_spt/scene/families.py``, whose line is rewritten with the names added (as
tests/scene/test_material_schema.py does for material kinds). Everything runs in a fresh process:
the registries are built at import from the rewritten list, and nothing else is told of the probes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from warp_spt.scene import families

ROOT = Path(__file__).resolve().parents[2]

# the fresh process's first lines: the rewritten list, then a finder for the probe modules
PREAMBLE = textwrap.dedent('''
    import importlib.abc, importlib.util, sys
    families_path, folder, package, line, new_line = sys.argv[1:6]
    src = open(families_path).read()
    assert line in src, "the registry line moved: " + line
    src = src.replace(line, new_line)                   # the one registry line
    spec = importlib.util.spec_from_loader("warp_spt.scene.families", loader=None)
    families = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = families
    exec(compile(src, families_path, "exec"), families.__dict__)


    class ProbeModules(importlib.abc.MetaPathFinder):
        """warp_spt.<package>.probe_NAME is the file probe_NAME.py of the folder."""

        def find_spec(self, name, path=None, target=None):
            if name.startswith(f"warp_spt.{package}.probe_"):
                return importlib.util.spec_from_file_location(name, f"{folder}/{name.rsplit('.', 1)[1]}.py")
            return None


    sys.meta_path.insert(0, ProbeModules())
''')


def _line(variable: str, names: tuple[str, ...]) -> str:
    return f"{variable}: tuple[str, ...] = (" + ", ".join(f'"{n}"' for n in names) + ")"


def run_probe(folder: Path, variable: str, package: str, modules: dict[str, str], script: str) -> str:
    """Run ``script`` in a fresh process after adding ``modules`` (name -> source; each name must start
    with ``probe_``) to ``families.<variable>`` as kinds of ``warp_spt.<package>``; returns its stdout,
    asserting it ends with "ok"."""
    for name, source in modules.items():
        (folder / f"{name}.py").write_text(textwrap.dedent(source))
    (folder / "probe_main.py").write_text(PREAMBLE + textwrap.dedent(script))
    names = getattr(families, variable)
    args = [str(ROOT / "warp_spt" / "scene" / "families.py"), str(folder), package, _line(variable, names),
            _line(variable, names + tuple(modules))]
    # the kernel index keys kernels by this package's sources alone: a probe's own source is not among them
    env = {**os.environ, "PYTHONPATH": str(ROOT), "WARP_SPT_KERNEL_INDEX": "0"}
    out = subprocess.run([sys.executable, str(folder / "probe_main.py"), *args], capture_output=True, text=True,
                         cwd=ROOT, env=env, timeout=900)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-4000:] + out.stdout[-2000:]
    return out.stdout
