"""Input builders for the torture cases: designs, deep JSON, CSV data, profiles, calibrations, and real
rodfab jobs (made by the binary under test, then tampered with) written as hostile zips or folders."""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import shutil
import struct
import zipfile
import zlib
from pathlib import Path
from typing import Callable

DEEP = 60000  # nesting levels of the "deep JSON" inputs (the issue: ~60,000)


# --- designs ---------------------------------------------------------------------------------------------

def clamped_knots(n: int, degree: int) -> list[float]:
    """Open uniform knot vector for n control points."""
    inner = n - degree - 1
    return [0.0] * (degree + 1) + [(i + 1) / (inner + 1) for i in range(inner)] + [1.0] * (degree + 1)


def rod(name: str, points: list, degree: int = 1, knots=None, weights=None, diameter: float = 1.0,
        section=None, modulus=50.0, **extra) -> dict:
    r = {"name": name,
         "centerline": {"degree": degree, "knots": knots if knots is not None else clamped_knots(len(points), degree),
                        "points": points},
         "section": section if section is not None else {"shape": "circle", "diameter": diameter},
         "modulus": modulus}
    if weights is not None:
        r["centerline"]["weights"] = weights
    r.update(extra)
    return r


def design_dict(*rods: dict, **top) -> dict:
    d = {"format": "rodfab.design/1", "units": "mm", "rods": list(rods)}
    d.update(top)
    return d


def design(*rods: dict, **top) -> str:
    return json.dumps(design_dict(*rods, **top), indent=1)


def bar(length: float = 4.0, name: str = "bar", **kw) -> dict:
    """A short straight rod along x: a job of ~30 layers in a fraction of a second."""
    kw.setdefault("modulus", {"degree": 1, "knots": [0, 0, 1, 1], "values": [8, 150]})
    return rod(name, [[0, 0, 0], [length, 0, 0]], **kw)


BAR = design(bar())

# The README's example rod (3 mm cubic), the starting point of the runaway designs.
README_CENTERLINE = {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "points": [[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0]],
                     "weights": [1, 1, 1, 1]}
README_MODULUS = {"degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [8, 120, 40]}


def readme_rod(centerline=None, section=None, **extra) -> dict:
    r = {"name": "edge-0", "centerline": copy.deepcopy(centerline or README_CENTERLINE),
         "section": section or {"shape": "circle", "diameter": 1.5}, "normal": [0, 0, 1],
         "modulus": copy.deepcopy(README_MODULUS)}
    r.update(extra)
    return r


def with_mechanics(d: dict, rod_name: str, force=(0, 0, -0.01), steps: int = 2) -> dict:
    """Clamps the rod's start and loads its end, so that `rodfab simulate` has something to solve."""
    d = copy.deepcopy(d)
    d["mechanics"] = {"poisson_ratio": 0.4, "load_steps": steps,
                      "supports": [{"at": {"rod": rod_name, "end": "start"}, "type": "clamped"}],
                      "loads": [{"at": {"rod": rod_name, "end": "end"}, "force": list(force)}]}
    return d


def cantilever(length: float = 20.0, moment: float = 0.5, steps: int = 3) -> dict:
    return {"format": "rodfab.design/1", "units": "mm",
            "rods": [{"name": "beam", "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [length, 0, 0]]},
                      "section": {"shape": "circle", "diameter": 1.0}, "modulus": 100.0}],
            "mechanics": {"poisson_ratio": 0.4, "load_steps": steps,
                          "supports": [{"at": {"rod": "beam", "end": "start"}, "type": "clamped"}],
                          "loads": [{"at": {"point": [length, 0, 0]}, "moment": [0, 0, moment]}]}}


def polyline(points: list, name: str = "kinked", **kw) -> dict:
    return rod(name, points, degree=1, **kw)


def bent(angle_deg: float, plane: str = "xy", length: float = 3.0) -> list:
    """Two straight segments; the second turned by angle_deg from the first, within the plane."""
    a = math.radians(angle_deg)
    first, turned = {"xy": ((1, 0, 0), (math.cos(a), math.sin(a), 0)),
                     "xz": ((1, 0, 0), (math.cos(a), 0, math.sin(a))),
                     "yz": ((0, 1, 0), (0, math.cos(a), math.sin(a)))}[plane]
    p1 = [first[i] * length for i in range(3)]
    return [[0.0, 0.0, 0.0], p1, [p1[i] + turned[i] * length for i in range(3)]]


def dither_report(**options: str) -> list[str]:
    """`rodfab dither-report` on a small workload (a fraction of a second), with some options replaced."""
    opts = {"--dither": "white", "--block": "16x16x16", "--fractions": "0.5", "--rod-length": "2"}
    opts.update(options)
    return ["dither-report"] + [a for kv in opts.items() for a in kv]


# --- deep and odd JSON -----------------------------------------------------------------------------------

def deep_array(n: int = DEEP) -> str:
    return "[" * n + "]" * n


def deep_object(n: int = DEEP) -> str:
    return '{"a":' * n + "1" + "}" * n


def with_deep(doc: dict, path: list, deep: str | None = None) -> str:
    """doc as JSON with the value at `path` (keys / indices) replaced by a deeply nested value."""
    marker = "\u2063DEEP\u2063"
    d = copy.deepcopy(doc)
    node = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = marker
    text = json.dumps(d, indent=1)
    return text.replace(json.dumps(marker), deep if deep is not None else deep_array())


def duplicate_key(doc: dict, path: list, key: str, value) -> str:
    """doc as JSON with `key` written twice in the object at `path`, the second time with `value`."""
    marker = "\u2063DUP\u2063"
    d = copy.deepcopy(doc)
    node = d
    for k in path:
        node = node[k]
    node[marker] = 0
    text = json.dumps(d, indent=1)
    return text.replace(json.dumps(marker) + ": 0", json.dumps(key) + ": " + json.dumps(value))


def raw_number(doc: dict, path: list, literal: str) -> str:
    """doc as JSON with the value at `path` written as a literal number JSON's float cannot hold
    (1e309, -1e400, ...)."""
    marker = "\u2063NUM\u2063"
    d = copy.deepcopy(doc)
    node = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = marker
    return json.dumps(d, indent=1).replace(json.dumps(marker), literal)


# --- profiles and calibrations ---------------------------------------------------------------------------

def bundled_profile(src: Path) -> dict:
    return json.loads((src / "printer_profiles" / "stratasys-objet500-connex3.json").read_text())


def bundled_calibration(src: Path) -> dict:
    return json.loads((src / "examples" / "calibration" / "default-60C.json").read_text())


def profile_file(edit: Callable[[dict], None] | None = None, text: Callable[[dict], str] | None = None):
    """A builder: the bundled Connex3 profile, edited (or rendered by `text`), written to the path."""
    def build(path: Path, ctx) -> None:
        p = bundled_profile(ctx.src)
        if edit:
            edit(p)
        path.write_text(text(p) if text else json.dumps(p, indent=1))
    return build


def calibration_file(edit: Callable[[dict], None] | None = None, text: Callable[[dict], str] | None = None):
    def build(path: Path, ctx) -> None:
        c = bundled_calibration(ctx.src)
        if edit:
            edit(c)
        path.write_text(text(c) if text else json.dumps(c, indent=1))
    return build


def csv_rows(rows: list[tuple], header: str = "vero_fraction,modulus_mpa") -> str:
    return header + "\n" + "".join(",".join(str(v) for v in r) + "\n" for r in rows)


def dma_rows(n: int, spread: float = 0.0) -> list[tuple]:
    """n distinct Vero fractions on a Lichtenecker-like curve (log E linear in the fraction),
    0.5 MPa at 0 to 190 MPa at 1, optionally with a deterministic scatter of +-spread (relative)."""
    rows = []
    for i in range(n):
        f = i / (n - 1)
        e = 0.5 * (190 / 0.5) ** f * (1 + spread * math.sin(7.3 * i))
        rows.append((f"{f:.6f}", f"{e:.6g}"))
    return rows


# --- callables that build special files ------------------------------------------------------------------

def fifo(path: Path, ctx) -> None:
    os.mkfifo(path)


def symlink_to(target: str):
    def build(path: Path, ctx) -> None:
        os.symlink(target, path)
    return build


def folder(files: dict[str, str | bytes]):
    """A user's folder with some content (including a hidden file and a subfolder)."""
    def build(path: Path, ctx) -> None:
        path.mkdir(parents=True, exist_ok=True)
        for name, content in files.items():
            p = path / name
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(content if isinstance(content, bytes) else content.encode())
    return build


USER_FILES = {"thesis.tex": "\\documentclass{article}\n% months of work\n", "data/run-1.csv": "t,x\n0,1\n1,2\n",
              ".git-like-config": "[core]\n", "photos/rod.png": b"\x89PNG\r\n\x1a\n" + bytes(range(256))}


# --- jobs made by the binary under test, and hostile variants ---------------------------------------------

def job(fmt: str = "zip", design_text: str = BAR, extra: tuple = ()):
    """A builder that copies a real job (sliced once per run from `design_text`)."""
    def build(path: Path, ctx) -> None:
        key = "job-" + hashlib.sha256((fmt + design_text + repr(extra)).encode()).hexdigest()[:12]

        def make(out: Path) -> None:
            out.mkdir()
            (out / "d.json").write_text(design_text)
            name = "job.zip" if fmt == "zip" else "job"
            ctx.run_rodfab(["slice", "d.json", "-o", name, "--format", fmt, "--quiet", *extra], cwd=out)

        made = ctx.cached(key, make) / ("job.zip" if fmt == "zip" else "job")
        if made.is_dir():
            shutil.copytree(made, path, symlinks=True)
        else:
            shutil.copyfile(made, path)
    return build


def read_zip(path: Path) -> list[tuple[str, bytes]]:
    with zipfile.ZipFile(path) as z:
        return [(i.filename, z.read(i)) for i in z.infolist()]


class Entry:
    """A zip entry written exactly as told: name, stored bytes, method, and the declared CRC and sizes
    (defaults: the honest ones)."""

    def __init__(self, name: str, data: bytes = b"", method: int = 8, compressed: bytes | None = None,
                 crc: int | None = None, size: int | None = None, flags: int = 0, mode: int = 0o100644):
        self.name, self.method, self.flags, self.mode = name, method, flags, mode
        if compressed is None:
            if method == 8:
                c = zlib.compressobj(6, zlib.DEFLATED, -15)
                compressed = c.compress(data) + c.flush()
            else:
                compressed = data
        self.compressed = compressed
        self.crc = zlib.crc32(data) if crc is None else crc
        self.size = len(data) if size is None else size


def write_zip(path: Path, entries: list[Entry], declared_entries: int | None = None) -> None:
    """A zip written byte by byte (no zip64): lets a case declare sizes, names and counts that lie."""
    out = bytearray()
    central = bytearray()
    for e in entries:
        name = e.name.encode()
        offset = len(out)
        out += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, e.flags, e.method, 0, 0x21, e.crc,
                           len(e.compressed) & 0xFFFFFFFF, e.size & 0xFFFFFFFF, len(name), 0)
        out += name + e.compressed
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 0x031E, 20, e.flags, e.method, 0, 0x21, e.crc,
                               len(e.compressed) & 0xFFFFFFFF, e.size & 0xFFFFFFFF, len(name), 0, 0, 0, 0,
                               (e.mode << 16) & 0xFFFFFFFF, offset)
        central += name
    count = len(entries) if declared_entries is None else declared_entries
    eocd = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, count & 0xFFFF, count & 0xFFFF, len(central), len(out), 0)
    path.write_bytes(bytes(out + central + eocd))


def manifest_entry(data: bytes) -> dict:
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def tampered_zip(mutate: Callable[[list[Entry], dict], list[Entry] | None], fmt_design: str = BAR):
    """A builder: the real zip job's entries and manifest handed to `mutate(entries, manifest)`, which
    edits them (or returns a new entry list); the manifest is re-encoded as the first entry unless the
    mutation replaced manifest.json itself."""
    def build(path: Path, ctx) -> None:
        tmp = path.parent / (".fixture-" + path.name)
        job("zip", fmt_design)(tmp, ctx)
        raw = read_zip(tmp)
        tmp.unlink()
        manifest = json.loads(dict(raw)["manifest.json"])
        entries = [Entry(n, d, method=0 if n.endswith(".png") else 8) for n, d in raw if n != "manifest.json"]
        result = mutate(entries, manifest)
        entries = result if result is not None else entries
        if not any(e.name == "manifest.json" for e in entries):
            entries.insert(0, Entry("manifest.json", json.dumps(manifest, indent=1).encode()))
        write_zip(path, entries)
    return build


def tampered_dir(mutate: Callable[[Path, dict], None], fmt_design: str = BAR, rewrite_manifest: bool = True):
    """A builder: the real folder job copied, then `mutate(folder, manifest)`; the manifest is written
    back afterwards (unless rewrite_manifest is False, for mutations that replace it)."""
    def build(path: Path, ctx) -> None:
        job("dir", fmt_design)(path, ctx)
        manifest = json.loads((path / "manifest.json").read_text())
        mutate(path, manifest)
        if rewrite_manifest and (path / "manifest.json").is_file() and not (path / "manifest.json").is_symlink():
            (path / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return build


def zero_deflate(total: int, chunk: int = 16 << 20) -> tuple[bytes, int]:
    """A raw deflate stream of `total` zero bytes (a multiple of chunk) built from one full-flushed
    chunk repeated, and the CRC-32 of the zeros: a bomb of a few MB."""
    assert total % chunk == 0
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = c.compress(bytes(chunk)) + c.flush(zlib.Z_FULL_FLUSH)
    stream = block * (total // chunk) + b"\x03\x00"  # an empty final block ends the stream
    crc = 0
    zeros = bytes(chunk)
    for _ in range(total // chunk):
        crc = zlib.crc32(zeros, crc)
    return stream, crc


_bombs: dict[int, tuple[bytes, int]] = {}


def bomb(total: int) -> tuple[bytes, int]:
    if total not in _bombs:
        _bombs[total] = zero_deflate(total)
    return _bombs[total]


def remove_material(manifest: dict, material: str) -> list[str]:
    """Drops every image of one material from the manifest (files table, layers, statistics) and
    returns the file names dropped; the material stays declared."""
    gone = [n for n in manifest["files"] if n.startswith(material + "_")]
    for n in gone:
        del manifest["files"][n]
    for layer in manifest["layers"]:
        layer.get("files", {}).pop(material, None)
        layer.get("voxels", {}).pop(material, None)
    return gone
