"""The house's rules (docs/architecture.md), checked on the code's own imports, lazy ones included:

* no module imports from a layer above its own (the layers, bottom up, are LAYERS);
* no import circle between modules;
* the host side (scene/, io/) imports no Warp at module level.
"""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "warp_spt"

# Bottom up. io/ reads files into the host model without Warp, so it sits below core/ and may not
# import it at all (an MTL ``proc:`` map is read against scene/proctex_registry.py's declarations).
LAYERS = [
    {"runtime"},
    {"scene", "demo", "losses"},
    {"io"},
    {"core"},
    {"samplers"},
    {"integrators"},
    {"rendering"},
    {"diff"},
    {"cluster", "animation", "notebook"},
    {"cli", "viewer", "__init__", "__main__"},
]


def _module(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _layer(module: str) -> int:
    top = module.split(".")[1] if module.count(".") else "__init__"
    return next(k for k, names in enumerate(LAYERS) if top in names)


def _imports(path: Path) -> set[str]:
    """Every warp_spt module ``path`` imports, at any depth of its code (lazy imports count)."""
    me = _module(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("warp_spt.")}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            if not base.startswith("warp_spt"):
                continue
            for a in node.names:       # "from warp_spt.x import y": y may be a module
                sub = f"{base}.{a.name}"
                found.add(sub if (PKG.parent / (sub.replace(".", "/") + ".py")).exists()
                          or (PKG.parent / sub.replace(".", "/") / "__init__.py").exists() else base)
    return {m for m in found if m != "warp_spt"} - {me}


def _graph() -> dict[str, set[str]]:
    return {_module(p): _imports(p) for p in PKG.rglob("*.py")}


def test_no_module_imports_from_a_layer_above_its_own():
    upward = [f"{m} (layer {_layer(m)}) imports {t} (layer {_layer(t)})"
              for m, targets in _graph().items() for t in targets if _layer(t) > _layer(m)]
    assert not upward, "\n".join(upward)


def test_no_import_circles():
    graph = _graph()
    state: dict[str, int] = {}
    cycles = []

    def visit(m: str, stack: list[str]) -> None:
        state[m] = 1
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                cycles.append(" -> ".join(stack[stack.index(t):] + [t]))
            elif t not in state:
                visit(t, stack + [t])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, "\n".join(cycles)


def test_the_host_side_imports_no_warp_at_module_level():
    offenders = []
    for p in list((PKG / "scene").rglob("*.py")) + list((PKG / "io").rglob("*.py")):
        for node in ast.parse(p.read_text()).body:
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n == "warp" or n.startswith("warp.") for n in names):
                offenders.append(str(p.relative_to(PKG)))
    assert not offenders, offenders
