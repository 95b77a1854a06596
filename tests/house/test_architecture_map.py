"""docs/architecture.md is a map of the package that stays true.

* its package table ("What each package owns") has a row for every subpackage of ``warp_spt/``
  (every folder with an ``__init__.py``) and one for the flat modules, and each row names every
  module of its package (``name.py`` in backticks);
* every path the document names in backticks exists: ``warp_spt/...``, ``tests/...``,
  ``benchmarks/...``, ``scripts/...``, ``examples/...``, ``notebooks/...`` files, and the short forms
  ``accel/surface.py`` or ``rendering/setup.KERNEL_KINDS`` (a package of ``warp_spt/``, a module in
  it, and a name that module defines or mentions); a short form whose first folder is no package
  (``core/bvh.py`` after a move) is an error.
"""

from __future__ import annotations

import re

from tests.conftest import REPO

DOC = REPO / "docs" / "architecture.md"
PKG = REPO / "warp_spt"
FLAT = "flat modules"
ROOTS = ("warp_spt", "tests", "benchmarks", "scripts", "examples", "notebooks")
CODE = re.compile(r"`([^`\n]+)`")


def package_table(text: str) -> dict[str, str]:
    """{first cell without backticks, e.g. "accel/" or "flat modules": the row's other cells}."""
    section = text.split("## What each package owns", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2 or set(cells[0]) <= set("-: ") or cells[0] == "package":
            continue
        rows[cells[0].strip("`")] = " | ".join(cells[1:])
    return rows


def subpackages() -> list[str]:
    return sorted(str(p.parent.relative_to(PKG)) + "/" for p in PKG.rglob("__init__.py") if p.parent != PKG)


def modules_of(folder) -> list[str]:
    return sorted(p.name for p in folder.glob("*.py") if p.name != "__init__.py")


def test_the_package_table_names_every_package_and_its_modules():
    rows = package_table(DOC.read_text(encoding="utf-8"))
    missing = [pkg for pkg in subpackages() if pkg not in rows]
    assert not missing, f"docs/architecture.md's package table has no row for {missing}"
    assert FLAT in rows, "docs/architecture.md's package table has no 'flat modules' row"
    unnamed = []
    for pkg in subpackages():
        named = set(CODE.findall(rows[pkg]))
        unnamed += [f"{pkg}{m}" for m in modules_of(PKG / pkg) if m not in named]
    named = set(CODE.findall(rows[FLAT]))
    unnamed += [m for m in sorted(p.name for p in PKG.glob("*.py")) if m not in named]
    assert not unnamed, f"docs/architecture.md's package table does not name {unnamed}"
    stale = [pkg for pkg in rows if pkg != FLAT and not (PKG / pkg / "__init__.py").exists()]
    assert not stale, f"docs/architecture.md's package table names packages that do not exist: {stale}"


def named_paths(text: str) -> list[str]:
    return [c.rstrip(".,;:") for c in CODE.findall(text)]


def problem(name: str) -> str | None:
    """Why the backticked ``name`` does not point at something that exists, or None (also for text
    that is not a path this test checks)."""
    if " " in name or "/" not in name or name.startswith((".", "/")):
        return None
    if re.search(r"(^|/)[A-Z]+(\.|$)", name):      # a recipe's placeholder: bsdfs/NAME.py, io/FORMAT.py
        return None
    if name.endswith("/"):                          # a folder: "accel/", "integrators/guided/"
        folder = name.rstrip("/")
        where = REPO / folder if folder.split("/")[0] in ROOTS else PKG / folder
        if folder.split("/")[0] in ROOTS or (PKG / folder.split("/")[0]).is_dir():
            return None if where.is_dir() else "no such folder"
        return None
    head = name.split("/")[0]
    base = REPO if head in ROOTS else PKG if (PKG / head).is_dir() else None
    if base is None:       # a folder inside a package ("static/viewer.js"), or a package that is gone
        inside = [d for d in PKG.rglob(head) if d.is_dir() and (d.parent / name).exists()]
        return None if inside else "no such package or folder"
    if re.fullmatch(r"[\w/.-]+\.(py|ipynb|js|html|json|md)", name):
        return None if (base / name).is_file() else "no such file"
    m = re.fullmatch(r"([\w/]+)/(\w+)\.(\w+)(?:\.\w+)*(?:\(.*\))?", name)
    if not m:
        return None
    folder, module, attr = m.groups()
    path = base / folder / f"{module}.py"
    if not path.is_file():
        path = base / folder / module / "__init__.py"
        if not path.is_file():
            return f"no module {folder}/{module}"
    if not re.search(rf"\b{re.escape(attr)}\b", path.read_text(encoding="utf-8")):
        return f"{path.relative_to(REPO)} has no {attr!r}"
    return None


def test_every_module_path_the_document_names_exists():
    bad = sorted({f"`{n}`: {why}" for n in named_paths(DOC.read_text(encoding="utf-8")) if (why := problem(n))})
    assert not bad, "docs/architecture.md names what does not exist:\n" + "\n".join(bad)


def test_the_checks_can_fail():
    """The two checks above are not vacuous: a row taken out and stale paths are found."""
    text = DOC.read_text(encoding="utf-8")
    rows = package_table(text)
    assert len(rows) == len(subpackages()) + 1, sorted(rows)
    without = "\n".join(line for line in text.splitlines() if not line.startswith("| `accel/` |"))
    assert "accel/" not in package_table(without)
    assert problem("core/geometry.py") == "no such package or folder"
    assert problem("core/material_table.with_gradients") == "no such package or folder"
    assert problem("static/viewer.js") is None
    assert problem("bsdfs/NAME.py") is None                  # a placeholder
    assert problem("warp_spt/core/geometry.py") == "no such file"
    assert problem("accel/geometry.py") == "no such file"
    assert problem("accel/surface.NO_SUCH_NAME") is not None
    assert problem("accel/surface.OFFSET_REL") is None
    assert problem("integrators/guided/tree.py") is None
    assert problem("integrators/guiding_tree.py") == "no such file"
