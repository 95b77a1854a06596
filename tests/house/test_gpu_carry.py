"""benchmarks/gpu_carry.py: the wheels for a GPU machine without network access, cut into parts and joined
again there. Small made-up wheels stand in for Warp's, Mitsuba's and drjit's."""

from __future__ import annotations

import base64
import hashlib
import importlib.util
import random
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def carry():
    spec = importlib.util.spec_from_file_location("gpu_carry", REPO / "benchmarks" / "gpu_carry.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def make_wheel(folder: Path, dist: str, package: str, files: dict[str, bytes]) -> Path:
    """A minimal valid wheel of ``dist`` 1.0 holding ``files`` (paths inside ``package``)."""
    info = f"{dist}-1.0.dist-info"
    members = {f"{package}/{k}": v for k, v in files.items()}
    members[f"{info}/METADATA"] = f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n".encode()
    members[f"{info}/WHEEL"] = b"Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n"
    record = [record_line(k, v) for k, v in members.items()] + [f"{info}/RECORD,,"]
    members[f"{info}/RECORD"] = ("\n".join(record) + "\n").encode()
    path = folder / f"{dist}-1.0-py3-none-any.whl"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for k, v in members.items():
            z.writestr(k, v)
    return path


@pytest.fixture
def wheels(tmp_path):
    folder = tmp_path / "wheels"
    folder.mkdir()
    blob = random.Random(3).randbytes(60_000)       # incompressible: the parts really split it
    make_wheel(folder, "warp_lang", "warp", {"__init__.py": b"VERSION = 1\n", "bin/warp.so": blob})
    make_wheel(folder, "drjit", "drjit", {"__init__.py": b""})
    make_wheel(folder, "mitsuba", "mitsuba", {
        "__init__.py": b"",
        "libmitsuba.so": b"shared" * 100,
        "cuda_ad_rgb.cpython-312-x86_64-linux-gnu.so": b"cuda rgb",
        "scalar_rgb.cpython-312-x86_64-linux-gnu.so": b"scalar rgb",
        "llvm_ad_rgb.cpython-312-x86_64-linux-gnu.so": b"llvm rgb" * 1000,
        "cuda_ad_spectral_polarized.cpython-312-x86_64-linux-gnu.so": b"spectral",
        "llvm_ad_rgb/__init__.pyi": b"stub",
        "plugins/path.so": b"plugin",
    })
    return folder


def test_parts_fit_their_size_and_join_into_the_same_wheels_that_pip_installs(carry, wheels, tmp_path, capsys):
    out = tmp_path / ".carry"
    assert carry.prepare(wheels, out, part_mib=0.02) == 0
    parts = sorted(int(p.name) for p in out.iterdir())
    assert parts == list(range(1, len(parts) + 1)) and len(parts) >= 3      # 60 kB of Warp over 20 kB parts
    for p in parts:
        pieces = [f for f in (out / str(p)).iterdir() if f.name != "manifest.json"]
        assert sum(f.stat().st_size for f in pieces) <= 0.02 * (1 << 20)
    printed = capsys.readouterr().out
    assert f'carry [".carry/{parts[-1]}"]' in printed and "gpu_carry.py install /tmp/stage" in printed

    stage = tmp_path / "stage"
    stage.mkdir()
    for p in parts[1:]:                     # a fresh machine got only the later parts
        for f in (out / str(p)).iterdir():
            shutil.copy(f, stage)
    assert carry.install(stage, tmp_path / "site") == 3
    assert "lacks part(s) 1 of" in capsys.readouterr().out
    for f in (out / "1").iterdir():
        shutil.copy(f, stage)
    assert carry.install(stage, tmp_path / "site") == 0

    site = tmp_path / "site"
    assert (site / "warp" / "bin" / "warp.so").read_bytes() == zipfile.ZipFile(
        next(wheels.glob("warp_lang*"))).read("warp/bin/warp.so")
    kept = sorted(f.name for f in (site / "mitsuba").iterdir() if f.suffix == ".so")
    assert kept == ["cuda_ad_rgb.cpython-312-x86_64-linux-gnu.so", "libmitsuba.so",
                    "scalar_rgb.cpython-312-x86_64-linux-gnu.so"]
    assert not (site / "mitsuba" / "llvm_ad_rgb").exists() and (site / "mitsuba" / "plugins" / "path.so").exists()
    found = subprocess.run([sys.executable, "-c", "import warp, mitsuba, drjit; print(warp.VERSION)"],
                           cwd=tmp_path, env={"PYTHONPATH": str(site)}, capture_output=True, text=True)
    assert found.stdout.strip() == "1", found.stderr


def test_a_corrupted_piece_is_refused_before_pip_sees_it(carry, wheels, tmp_path, capsys):
    out = tmp_path / ".carry"
    carry.prepare(wheels, out, part_mib=1.0)
    stage = tmp_path / "stage"
    shutil.copytree(out / "1", stage)
    piece = next(f for f in stage.iterdir() if f.name.startswith("warp_lang"))
    data = bytearray(piece.read_bytes())
    data[1000] ^= 0xFF
    piece.write_bytes(bytes(data))
    assert carry.install(stage, tmp_path / "site") == 4
    assert "warp_lang-1.0-py3-none-any.whl does not match its manifest" in capsys.readouterr().out
    assert not (tmp_path / "site").exists()


def test_prepare_names_the_wheel_it_lacks(carry, wheels, tmp_path, capsys):
    next(wheels.glob("drjit*")).unlink()
    assert carry.prepare(wheels, tmp_path / ".carry", part_mib=1.0) == 2
    assert "has no wheel of drjit" in capsys.readouterr().out
