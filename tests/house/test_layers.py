"""The house's rules (docs/architecture.md), checked on the code's own imports, lazy ones included:

* no module imports from a layer above its own (the layers, bottom up, are LAYERS);
* no import circle between modules;
* the host side (scene/, io/, gltf/, images/) imports no Warp at module level.
"""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[2] / "warp_spt"

# Bottom up. io/ reads files into the host model without Warp, so it sits below the device families
# and may not import them at all (an MTL ``proc:`` map is read against scene/proctex_registry.py's
# declarations); gltf/ is a reader of the same floor, a room of its own for its size. device/ holds
# what every kernel reads; accel/ the ray queries on it; the plugin families (bsdfs, emitters, media)
# share one floor and never import each other; upload/ fills them all.
LAYERS = [
    {"runtime"},
    {"scene", "demo", "losses"},
    {"io", "gltf", "usd", "images"},
    {"device"},
    {"accel"},
    {"bsdfs", "emitters", "media"},
    {"upload"},
    {"samplers"},
    {"integrators"},
    {"rendering"},
    {"diff"},
    {"cluster", "animation", "notebook"},
    {"cli", "viewer", "__init__", "__main__"},
]
# The plugin families of one floor: a module of one imports nothing of another (shared code lives below).
FAMILIES = ("bsdfs", "emitters", "media")


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
    for p in [q for room in ("scene", "io", "gltf", "usd", "images") for q in (PKG / room).rglob("*.py")]:
        for node in ast.parse(p.read_text()).body:
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n == "warp" or n.startswith("warp.") for n in names):
                offenders.append(str(p.relative_to(PKG)))
    assert not offenders, offenders


def test_plugin_families_never_import_each_other():
    def family(module: str) -> str | None:
        top = module.split(".")[1] if module.count(".") else ""
        return top if top in FAMILIES else None

    crossing = [f"{m} imports {t}" for m, targets in _graph().items() for t in targets
                if family(m) and family(t) and family(m) != family(t)]
    assert not crossing, "\n".join(crossing)


def test_no_room_holds_more_than_about_an_eighth_of_the_package():
    """A room (a subpackage, or the flat modules together) of more than ~12% of the package's lines is a
    drawer that has swallowed families: split it by what it holds."""
    lines: dict[str, int] = {}
    for p in PKG.rglob("*.py"):
        rel = p.relative_to(PKG).parts
        room = rel[0] if len(rel) > 1 else "(flat)"
        lines[room] = lines.get(room, 0) + len(p.read_text().splitlines())
    total = sum(lines.values())
    big = {room: f"{n / total:.1%}" for room, n in lines.items() if n > 0.13 * total}
    assert not big, big
