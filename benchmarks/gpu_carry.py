"""Wheels for a GPU machine without network access (Warp, Mitsuba, drjit), in parts that fit one call.

    python benchmarks/gpu_carry.py prepare WHEELS [--out .carry] [--part-mib 44]
    python benchmarks/gpu_carry.py install STAGE --target /tmp/site     # there, after the last part

The device tool sends the working tree and at most 64 MiB with each command; Warp's wheel alone is
149 MB (its ``warp.so`` is 299 MB unpacked, 85 MB even under ``zstd -19``), Mitsuba's 63 MB, so the
GPU check's packages cannot travel in one command. ``prepare`` takes the wheels for the GPU
machine's Python (3.12 there; fetch them here with the ``pip download`` line below), trims Mitsuba's
to the variants the check uses (``cuda_ad_rgb`` and ``scalar_rgb``: the spectral, polarised, mono and
LLVM variants are a third of its size), and cuts the bytes of all of them into numbered folders
``OUT/1``, ``OUT/2``, ... of at most ``--part-mib`` each (the rest of the 64 MiB is the working
tree), with ``OUT/manifest.json`` (each wheel's name, size and SHA-256, and which part holds which
piece). It prints the commands: each carries one folder and appends its pieces to a stage folder on
the machine (a machine stays warm, with its files, for about 30 s after a command: run them back to
back); the last one runs ``install``, which checks every wheel against the manifest, says which part
is missing when one is (the machine was a fresh one), installs them with pip without an index, and
then the check runs with ``PYTHONPATH`` pointing there.

    pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \\
        --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \\
        -d WHEELS warp-lang==1.19.0 mitsuba==3.9.1 drjit==1.5.0
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

KEEP_VARIANTS = ("cuda_ad_rgb", "scalar_rgb")
MIB = 1 << 20


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(MIB), b""):
            h.update(block)
    return h.hexdigest()


def variant_of(member: str) -> str | None:
    """The Mitsuba variant a wheel member belongs to (``mitsuba/llvm_ad_rgb.cpython-...so``,
    ``mitsuba/llvm_ad_rgb/...``), or None for shared files."""
    parts = member.split("/")
    if len(parts) < 2 or parts[0] != "mitsuba":
        return None
    head = parts[1].split(".")[0]
    kinds = ("scalar_", "llvm_", "cuda_")
    return head if head.startswith(kinds) and (len(parts) > 2 or parts[1].endswith((".so", ".pyi"))) else None


def trimmed_mitsuba(src: Path, dst: Path) -> tuple[int, int]:
    """Mitsuba's wheel without the variants the check does not use; its RECORD rewritten to match
    (pip checks a wheel's files against it). Returns (members dropped, bytes dropped unpacked)."""
    dropped, dropped_bytes = 0, 0
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        gone = set()
        for info in zin.infolist():
            v = variant_of(info.filename)
            if v is not None and v not in KEEP_VARIANTS:
                gone.add(info.filename)
                dropped, dropped_bytes = dropped + 1, dropped_bytes + info.file_size
        for info in zin.infolist():
            if info.filename in gone:
                continue
            data = zin.read(info)
            if info.filename.endswith(".dist-info/RECORD"):
                lines = [ln for ln in data.decode().splitlines() if ln.split(",")[0] not in gone]
                data = ("\n".join(lines) + "\n").encode()
            zout.writestr(info, data, compress_type=zipfile.ZIP_DEFLATED)
    return dropped, dropped_bytes


def prepare(wheels: Path, out: Path, part_mib: float) -> int:
    found = sorted(wheels.glob("*.whl"))
    names = {w.name.split("-")[0].lower().replace("_", "-"): w for w in found}
    missing = [n for n in ("warp-lang", "mitsuba", "drjit") if n not in names]
    if missing:
        print(f"gpu_carry: {wheels} has no wheel of {', '.join(missing)} (see this script's pip download line)")
        return 2
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    work = out / "wheels"
    work.mkdir()
    chosen = []
    for name, wheel in sorted(names.items()):
        if name == "mitsuba":
            dst = work / wheel.name
            n, b = trimmed_mitsuba(wheel, dst)
            print(f"{wheel.name}: {wheel.stat().st_size / MIB:.1f} MiB -> {dst.stat().st_size / MIB:.1f} MiB "
                  f"({n} files of the unused variants, {b / MIB:.0f} MiB unpacked, left out)")
        else:
            dst = work / wheel.name
            shutil.copyfile(wheel, dst)
            print(f"{wheel.name}: {dst.stat().st_size / MIB:.1f} MiB")
        chosen.append(dst)
    limit = int(part_mib * MIB)
    manifest = {"wheels": [], "parts": 0}
    part, room = 0, 0
    for wheel in chosen:
        size = wheel.stat().st_size
        entry = {"name": wheel.name, "size": size, "sha256": sha256(wheel), "pieces": []}
        with wheel.open("rb") as f:
            offset = 0
            while offset < size:
                if room == 0:
                    part, room = part + 1, limit
                    (out / str(part)).mkdir()
                n = min(room, size - offset)
                piece = f"{wheel.name}.{offset:012d}"
                (out / str(part) / piece).write_bytes(f.read(n))
                entry["pieces"].append({"part": part, "file": piece, "offset": offset, "size": n})
                offset, room = offset + n, room - n
        manifest["wheels"].append(entry)
    manifest["parts"] = part
    shutil.rmtree(work)
    (out / str(part) / "manifest.json").write_text(json.dumps(manifest, indent=1))
    total = sum(w["size"] for w in manifest["wheels"])
    note = ("the repository's .gitignore keeps .carry/ out of the working tree that every command sends"
            if out.name == ".carry" else f"ignore {out.name}/ (.git/info/exclude), or every command sends it all")
    print(f"\n{total / MIB:.1f} MiB in {part} parts of at most {part_mib:g} MiB under {out}/ ({note})")
    print("Commands, one device call each, back to back (carry the part named):")
    for k in range(1, part + 1):
        cmd = f"mkdir -p /tmp/stage && cp {out.name}/{k}/* /tmp/stage/ && ls /tmp/stage | wc -l"
        if k == part:
            cmd += (f" && python3 benchmarks/gpu_carry.py install /tmp/stage --target /tmp/site && "
                    f"PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1 python3 benchmarks/gpu_check.py")
        print(f"  carry [\"{out.name}/{k}\"]: {cmd}")
    return 0


def install(stage: Path, target: Path) -> int:
    if not (stage / "manifest.json").exists():
        print(f"gpu_carry: the stage {stage} has no manifest.json (it comes with the last part): send every part, "
              f"back to back")
        return 3
    manifest = json.loads((stage / "manifest.json").read_text())
    absent = sorted({p["part"] for w in manifest["wheels"] for p in w["pieces"] if not (stage / p["file"]).exists()})
    if absent:
        print(f"gpu_carry: the stage {stage} lacks part(s) {', '.join(map(str, absent))} of {manifest['parts']} "
              f"(a fresh machine: send them again, back to back)")
        return 3
    built = stage / "wheels"
    built.mkdir(exist_ok=True)
    for w in manifest["wheels"]:
        dst = built / w["name"]
        with dst.open("wb") as f:
            for p in sorted(w["pieces"], key=lambda p: p["offset"]):
                f.write((stage / p["file"]).read_bytes())
        if dst.stat().st_size != w["size"] or sha256(dst) != w["sha256"]:
            print(f"gpu_carry: {w['name']} does not match its manifest (size or SHA-256): send its parts again")
            return 4
    cmd = [sys.executable, "-m", "pip", "install", "-q", "--no-index", "--no-deps", "--no-compile",
           "--no-cache-dir", "--upgrade", "--target", str(target), *map(str, sorted(built.glob("*.whl")))]
    status = subprocess.run(cmd).returncode
    print(f"gpu_carry: {len(manifest['wheels'])} wheels installed into {target}" if status == 0 else
          f"gpu_carry: pip exited with status {status}")
    return status


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="verb", required=True)
    p = sub.add_parser("prepare", help="here: trim and cut the wheels into parts")
    p.add_argument("wheels", type=Path)
    p.add_argument("--out", type=Path, default=Path(".carry"))
    p.add_argument("--part-mib", type=float, default=44.0,
                   help="MiB of wheel bytes per part (64 MiB a call, less the working tree)")
    i = sub.add_parser("install", help="there: join the parts, check them, pip install without an index")
    i.add_argument("stage", type=Path)
    i.add_argument("--target", type=Path, default=Path("/tmp/site"))
    args = ap.parse_args()
    if args.verb == "prepare":
        return prepare(args.wheels, args.out, args.part_mib)
    return install(args.stage, args.target)


if __name__ == "__main__":
    sys.exit(main())
