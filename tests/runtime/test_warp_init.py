"""The shared Clang precompiled header (runtime/warp_init.share_clang_pch) is read only by the Warp
installation that built it: a header names the absolute paths of the native headers it came from, and
once another virtual environment's Warp (same version, same kernel cache) is deleted Clang refuses it
("malformed or corrupted precompiled file") and every compile goes on without one."""

import os

from warp_spt.runtime.warp_init import PCH_FOLDER, pch_folder


def _native(root, text="// builtin\n"):
    os.makedirs(root, exist_ok=True)
    with open(os.path.join(root, "builtin.h"), "w") as f:
        f.write(text)
    return str(root)


def test_each_warp_installation_has_its_own_header_folder(tmp_path):
    a, b = _native(tmp_path / "venv_a" / "native"), _native(tmp_path / "venv_b" / "native")
    cache = str(tmp_path / "cache")
    fa, fb = pch_folder(cache, a), pch_folder(cache, b)
    assert fa != fb
    assert fa == pch_folder(cache, a)                        # the same installation keeps its folder
    assert os.path.dirname(fa) == os.path.join(cache, PCH_FOLDER)   # under the cache: cleared with it
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "venv_a")
    assert pch_folder(cache, str(link / "native")) == fa     # by real path


def test_a_reinstalled_warp_in_the_same_place_gets_a_new_folder(tmp_path):
    a = _native(tmp_path / "native")
    before = pch_folder(str(tmp_path), a)
    os.utime(os.path.join(a, "builtin.h"), ns=(1, 1))
    assert pch_folder(str(tmp_path), a) != before
