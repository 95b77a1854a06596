"""Where a scene file may read from: the rule every reader follows for the files a scene file names.

A scene file names other files: an OBJ its ``mtllib``, an MTL its texture maps and density grids, a
glTF its buffers and images. The file a name gives must lie, after symbolic links are resolved,
inside the folder of the file that names it (or below), however the name is written. An absolute
path elsewhere, a drive letter, ``..`` climbing out (percent-encoded as ``%2e%2e`` in a glTF URI
too) and a symbolic link that points outside are refused with a :class:`SceneError` naming the file, the line
or JSON pointer, and the way out. So a model from elsewhere cannot pull an image from anywhere on the
machine into its render, nor any readable file in as vertex bytes.

Two exceptions, both documented in ``docs/limits.md``:

* an MTL's texture maps may also lie inside the working directory: the seed's scenes name their maps
  relative to it (``renderRes/x.png``, SEMANTICS.md), and the render is started from there;
* a trusted scene: ``WARP_SPT_TRUST_PATHS=1`` in the environment (the command line's
  ``--trust-paths`` sets it) lifts the rule, for scenes one wrote oneself that share textures
  across folders. It is read each time a path is checked, never cached.

Only where a file lies is checked here; whether it can be read (a regular file, not a FIFO or a
device) is :func:`warp_spt.io.tokens.file_problem`'s.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

TRUST_ENV = "WARP_SPT_TRUST_PATHS"
OPT_OUT = f"for a scene you trust, --trust-paths or {TRUST_ENV}=1 lifts this"


def trusted() -> bool:
    """Whether the environment lifts the rule (``WARP_SPT_TRUST_PATHS`` set to anything but 0/empty)."""
    return os.environ.get(TRUST_ENV, "").strip() not in ("", "0")


@contextlib.contextmanager
def trusting(on: bool):
    """Within the block, the rule is lifted if ``on`` (the command line's ``--trust-paths``): the
    environment variable is set, so worker processes started inside inherit it, and put back after."""
    if not on:
        yield
        return
    before = os.environ.get(TRUST_ENV)
    os.environ[TRUST_ENV] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(TRUST_ENV, None)
        else:
            os.environ[TRUST_ENV] = before


def _inside(path: Path, root: Path) -> bool:
    try:
        return os.path.commonpath([os.path.realpath(path), os.path.realpath(root)]) == os.path.realpath(root)
    except ValueError:          # another drive (Windows)
        return False


def confine(name: str, folder: str | os.PathLike[str], what: str,
            also: tuple[str | os.PathLike[str], ...] = ()) -> tuple[list[Path], str | None]:
    """The places ``name`` may be read from, in order, and why none (or None): ``name`` joined to
    ``folder`` and to each of ``also`` (an absolute name is itself), when every one of them lies
    inside its root once links are resolved. Where a file lies is what counts, not how its name is
    written: an absolute name of a file in the folder is read (exporters write such names), one of a
    file elsewhere is not. ``what`` names the file's role in the message ("texture", "glTF
    buffer"...); ``\\`` is read as ``/``. A trusted environment (:func:`trusted`) keeps every place."""
    clean = name.replace("\\", "/")
    p = Path(clean)
    drive = len(clean) > 1 and clean[1] == ":" and not p.is_absolute()      # C:/x on a POSIX machine
    roots = (Path(folder), *map(Path, also))
    if trusted():
        return ([p] if p.is_absolute() or drive else [root / p for root in roots]), None
    if p.is_absolute() or drive:
        inside = [root for root in roots if not drive and _inside(p, root)]
        if inside:
            return [p], None
        return [], (f"{what} {name!r} is an absolute path outside {' and '.join(str(r) for r in roots)}; a scene "
                    f"file names files in its folder only ({OPT_OUT})")
    out = [root for root in roots if not _inside(root / p, root)]
    if not out:
        return [root / p for root in roots], None
    # a name that leads out of any root is refused, even where another root would hold it: a link in
    # the scene's folder that points away must not fall through to the working directory's file
    return [], (f"{what} {name!r} leads outside {out[0]} (through '..' or a symbolic link); a scene file "
                f"names files in its folder only ({OPT_OUT})")
