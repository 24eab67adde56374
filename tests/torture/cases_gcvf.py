"""Hostile GrabCAD Voxel Print jobs (.gcvf, the J750/J850 profile) for `rodfab inspect`: a real job
sliced by the binary under test, then its layers and ConfigFile.xml replaced by images that lie about
their size, colours outside the material list, other colour types, damaged or gigantic PNGs, XML that
is malformed, nested without end, defines entity bombs or external entities, or says other numbers;
layer names padded, missing or out of range. The manifest's checksums are updated, so each defect must be
found by the gcvf checks themselves. Each must fail (exit 1) with the job or entry named, within bounded
memory and time, reading no file outside the job."""

from __future__ import annotations

import hashlib
import json
import shutil
import struct
import zlib
from pathlib import Path

from engine import MiB, Case, Step
from fixtures import BAR, Entry, read_zip, write_zip

RSS = 256 * MiB
PROFILE = "stratasys-j750-j850"
JOB_PARTS = ["manifest", "ConfigFile.xml", "layer_", "previews/"]


def gcvf_job(path: Path, ctx) -> None:
    def make(out: Path) -> None:
        out.mkdir()
        (out / "d.json").write_text(BAR)
        ctx.run_rodfab(["slice", "d.json", "-o", "job.gcvf", "--profile", PROFILE, "--quiet"], cwd=out)
    shutil.copyfile(ctx.cached("gcvf-job", make) / "job.gcvf", path)


def chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png(width: int, height: int, pixel: bytes, colour: int = 6, depth: int = 8, rows: bytes | None = None) -> bytes:
    raw = rows if rows is not None else b"".join(b"\0" + pixel * width for _ in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)) +
            chunk(b"pHYs", struct.pack(">IIB", 23622, 11811, 1)) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def tampered(mutate):
    """A builder: the real .gcvf's files handed to mutate(files, manifest) (name -> bytes); checksums of
    the files the manifest lists are then recomputed, so only the gcvf checks can find the defect."""
    def build(path: Path, ctx) -> None:
        tmp = path.parent / (".fixture-" + path.name)
        gcvf_job(tmp, ctx)
        files = dict(read_zip(tmp))
        tmp.unlink()
        manifest = json.loads(files["manifest.json"])
        mutate(files, manifest)
        for name in list(manifest["files"]):
            if name in files:
                manifest["files"][name] = {"bytes": len(files[name]), "sha256": hashlib.sha256(files[name]).hexdigest()}
        files["manifest.json"] = json.dumps(manifest, indent=1).encode()
        write_zip(path, [Entry(n, d, method=0 if n.endswith(".png") else 8) for n, d in files.items()])
    return build


def defective(name: str, mutate, note: str, patterns: list[str] = (), timeout: float = 20) -> Case:
    job = "bad.gcvf"
    return Case(name, [Step(["inspect", job], expect={1}, where=[job, *JOB_PARTS], patterns=list(patterns), rss_limit=RSS,
                            timeout=timeout)], files={job: tampered(mutate)}, note=note)


def size(m: dict) -> tuple[int, int]:
    return m["image"]["width"], m["image"]["height"]


def xml_edit(old: bytes, new: bytes):
    def mutate(f: dict, m: dict) -> None:
        assert old in f["ConfigFile.xml"]
        f["ConfigFile.xml"] = f["ConfigFile.xml"].replace(old, new, 1)
    return mutate


def xml_set(text: bytes):
    def mutate(f: dict, m: dict) -> None:
        f["ConfigFile.xml"] = text
    return mutate


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    white = bytes([255, 255, 255, 255])

    # Layer images.
    cs.append(defective("foreign-colour", lambda f, m: f.update({"layer_0.png": png(*size(m), b"\x01\x02\x03\xff")}),
                        "a layer of a colour not in the material list", ["not in the material list"]))
    cs.append(defective("transparent-background", lambda f, m: f.update({"layer_1.png": png(*size(m), b"\x00\x00\x00\x00")}),
                        "a layer whose background has alpha 0 (another colour)", ["not in the material list"]))
    cs.append(defective("all-rigid-layer", lambda f, m: f.update({"layer_0.png": png(*size(m), white)}),
                        "a layer filled with the rigid colour: counts disagree", ["voxels"]))
    cs.append(defective("rgb-not-rgba", lambda f, m: f.update({"layer_0.png": png(*size(m), b"\xff\xff\xff", colour=2)}),
                        "an RGB layer", ["colour type 2"]))
    cs.append(defective("wider-layer", lambda f, m: f.update({"layer_0.png": png(size(m)[0] + 8, size(m)[1], b"\0\0\0\xff")}),
                        "a layer 8 pixels wider than the job", ["pixels"]))
    cs.append(defective("gigantic-ihdr", lambda f, m: f.update({"layer_0.png": png(60000, 60000, b"", rows=b"")}),
                        "a layer declaring 60000 x 60000 pixels (3.6 G pixels)", ["PNG declares 60000 x 60000 pixels"]))
    cs.append(defective("truncated-png", lambda f, m: f.update({"layer_0.png": f["layer_0.png"][:100]}),
                        "a truncated layer", ["PNG is damaged|truncated"]))
    cs.append(defective("not-a-png", lambda f, m: f.update({"layer_0.png": b"<GCVF/>" * 20}),
                        "a layer that is not a PNG", ["not a PNG"]))

    def inflating(f: dict, m: dict) -> None:  # an IDAT that inflates to far more than the image
        w, h = size(m)
        f["layer_0.png"] = png(w, h, b"", rows=bytes(64 << 20))
    cs.append(defective("idat-inflates-64MiB", inflating, "an IDAT holding 64 MiB for a small image", ["not in the material list|damaged"]))

    # Layer names.
    cs.append(defective("padded-name", lambda f, m: f.update({"layer_00.png": f["layer_0.png"]}),
                        "an extra layer_00.png", ["unexpected entry"]))
    cs.append(defective("missing-layer", lambda f, m: f.pop("layer_1.png"), "layer_1.png missing", ["missing"]))
    cs.append(defective("layer-past-the-end", lambda f, m: f.update({f"layer_{m['layer_count']}.png": f["layer_0.png"]}),
                        "one layer more than NumberOfSlices", ["unexpected entry"]))

    # ConfigFile.xml.
    cs.append(defective("xml-voxelcount", xml_edit(b"<VoxelCount>", b"<VoxelCount>9"), "a VoxelCount too large", ["VoxelCount"]))
    cs.append(defective("xml-negative-count", xml_edit(b"<VoxelCount>", b"<VoxelCount>-"), "a negative VoxelCount", ["VoxelCount"]))
    cs.append(defective("xml-slices", xml_edit(b"<NumberOfSlices>", b"<NumberOfSlices>1"), "NumberOfSlices wrong", ["NumberOfSlices"]))
    cs.append(defective("xml-thickness", xml_edit(b">27000<", b">30000<"), "the Connex3's layer", ["SliceThicknessNanoMeter"]))
    cs.append(defective("xml-dpi-swapped", xml_edit(b"<XDpi>600</XDpi>", b"<XDpi>300</XDpi>"), "x dpi 300", ["XDpi"]))
    cs.append(defective("xml-rgba", xml_edit(b"<RGBA>0 0 255 255</RGBA>", b"<RGBA>0 0 254 255</RGBA>"), "a colour changed", ["RGBA"]))
    cs.append(defective("xml-truncated", lambda f, m: f.update({"ConfigFile.xml": f["ConfigFile.xml"][:200]}),
                        "ConfigFile.xml cut short", ["well-formed"]))
    cs.append(defective("xml-empty", xml_set(b""), "an empty ConfigFile.xml", ["well-formed"]))
    cs.append(defective("xml-binary", xml_set(bytes(range(256)) * 8), "binary bytes", ["well-formed"]))
    cs.append(defective("xml-other-root", xml_set(b"<?xml version='1.0'?><Job/>"), "another root", ["root element"]))
    cs.append(defective("xml-deep", xml_set(b"<GCVF>" + b"<a>" * 20000 + b"</a>" * 20000 + b"</GCVF>"),
                        "20,000 nested elements", ["GCVF|well-formed"]))
    bomb = b"<?xml version='1.0'?><!DOCTYPE GCVF [<!ENTITY l0 'lol'>"
    for n in range(1, 10):
        bomb += b"<!ENTITY l%d '%s'>" % (n, b"".join(b"&l%d;" % (n - 1) for _ in range(10)))
    bomb += b"]><GCVF><Version>&l9;</Version></GCVF>"
    cs.append(defective("xml-billion-laughs", xml_set(bomb), "an entity bomb (10^9 'lol')", ["GCVF"]))
    cs.append(defective("xml-external-entity",
                        xml_set(b"<?xml version='1.0'?><!DOCTYPE GCVF [<!ENTITY x SYSTEM 'file:///dev/zero'>]>"
                                b"<GCVF><Version>&x;</Version></GCVF>"),
                        "an external entity naming /dev/zero", ["GCVF"], timeout=10))
    cs.append(defective("xml-external-dtd",
                        xml_set(b"<?xml version='1.0'?><!DOCTYPE GCVF SYSTEM 'http://198.51.100.1/gcvf.dtd'><GCVF/>"),
                        "an external DTD on the network", ["GCVF"], timeout=10))
    cs.append(defective("xml-too-large", xml_set(b"<GCVF>" + b" " * (1 << 20) + b"</GCVF>"),
                        "ConfigFile.xml of 1 MiB", ["ConfigFile.xml"]))
    cs.append(defective("xml-duplicate-list", xml_edit(b"</GCVF>", b"<MaterialList/></GCVF>"), "two MaterialLists",
                        ["appears 2 times"]))
    return cs
