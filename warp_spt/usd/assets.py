"""Where an asset a stage names (a texture, a dome light's map) may be read from, and its bytes.

USD's resolver gives a file beside the stage as a path, and a file inside a ``.usdz`` package as the
package's path with the file's in brackets (``/scenes/chair.usdz[textures/wood.png]``, nested
packages nesting the brackets). Either way the file on disk, the package for a packaged one, must
pass :func:`warp_spt.io.paths.confine` against the stage's folder: the folder and below, links
resolved first, so an absolute path or a link out of the folder is refused, whether it names an
image or a package holding one. A packaged file is read from the archive in memory through USD's
own resolver (``Ar``): nothing is extracted."""

from __future__ import annotations

from pathlib import Path

from warp_spt.io.paths import confine


def package_file(resolved: str) -> str | None:
    """The package of a packaged asset's resolved path (before its first bracket), None for a plain file."""
    if resolved.endswith("]") and "[" in resolved:
        return resolved[:resolved.index("[")]
    return None


def locate(resolved: str, stage: str, what: str) -> tuple[str, bool, str | None]:
    """(the name to read, whether it lies in a package, why it may not be read or None) for an asset's
    resolved path: a plain file's confined path, or a packaged one's resolved path, its package confined."""
    package = package_file(resolved)
    found, refused = confine(package or resolved, Path(stage).parent, what if package is None else f"{what}'s package")
    if refused:
        return "", False, refused
    return (resolved if package is not None else str(found[0])), package is not None, None


def package_bytes(resolved: str) -> bytes:
    """The bytes of a packaged asset, read from its package in memory (empty if USD cannot open it)."""
    from pxr import Ar

    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    return bytes(memoryview(asset.GetBuffer())) if asset else b""
