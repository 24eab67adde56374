"""An independent reader of GrabCAD Voxel Print files (.gcvf zips or their folder form), for the CLI
tests: PNG decoded here with zlib and the PNG specification's unfiltering (all five filters), the XML
with xml.etree, nothing shared with rodfab's writer. Checks the layout the issue and the public
examples describe and prints a JSON summary.

    gcvf_decode.py JOB [--expect-thickness-nm N]
"""

from __future__ import annotations

import json
import os
import re
import struct
import sys
import xml.etree.ElementTree as ET
import zipfile
import zlib


def read_job(path: str) -> dict[str, bytes]:
    if os.path.isdir(path):
        out = {}
        for root, _, files in os.walk(path):
            for f in files:
                full = os.path.join(root, f)
                out[os.path.relpath(full, path)] = open(full, "rb").read()
        return out
    with zipfile.ZipFile(path) as z:
        return {i.filename: z.read(i) for i in z.infolist()}


def paeth(a: int, b: int, c: int) -> int:
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    return a if pa <= pb and pa <= pc else (b if pb <= pc else c)


def decode_png(data: bytes) -> tuple[int, int, list[bytes], tuple[int, int] | None]:
    """8-bit RGBA only: (width, height, rows of 4 * width bytes, pHYs pixels per metre or None)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, phys, header = 8, b"", None, None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        assert zlib.crc32(kind + body) == struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])[0], "bad CRC"
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"pHYs":
            x, y, unit = struct.unpack(">IIB", body)
            phys = (x, y) if unit == 1 else None
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    assert (depth, colour, interlace) == (8, 6, 0), f"expected 8-bit RGBA without interlacing, got {header}"
    raw = zlib.decompress(idat)
    stride, bpp = 4 * width, 4
    assert len(raw) == height * (stride + 1)
    rows, prev = [], bytearray(stride)
    for r in range(height):
        f = raw[r * (stride + 1)]
        line = bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                line[i] = (line[i] + paeth(a, b, c)) & 255
            else:
                assert f == 0, f"filter type {f}"
        rows.append(bytes(line))
        prev = line
    return width, height, rows, phys


def text(root: ET.Element, path: str) -> str:
    found = root.findall(path)
    assert len(found) == 1, f"{path}: found {len(found)} elements"
    return (found[0].text or "").strip()


def main() -> None:
    job = read_job(sys.argv[1])
    want_nm = int(sys.argv[sys.argv.index("--expect-thickness-nm") + 1]) if "--expect-thickness-nm" in sys.argv else None
    root = ET.fromstring(job["ConfigFile.xml"])
    assert root.tag == "GCVF"
    assert text(root, "Version") == "2"
    assert (text(root, "Resolution/XDpi"), text(root, "Resolution/YDpi")) == ("600", "300")
    nm = int(text(root, "Resolution/SliceThicknessNanoMeter"))
    if want_nm is not None:
        assert nm == want_nm, f"SliceThicknessNanoMeter {nm}, expected {want_nm}"
    assert text(root, "DataSemantics") == "Materials"
    assert text(root, "MaxNumberOfColors") == "6"
    prefix = text(root, "ImageFilePrefix")
    width, height = int(text(root, "SliceDimensions/SliceWidth")), int(text(root, "SliceDimensions/SliceHeight"))
    assert text(root, "SliceRange/StartIndex") == "0"
    layers = int(text(root, "SliceRange/NumberOfSlices"))
    background = tuple(int(v) for v in text(root, "MaterialList/BackGroundMaterialRGBA").split())
    materials = {}
    for m in root.findall("MaterialList/Material"):
        rgba = tuple(int(v) for v in m.find("RGBA").text.split())
        assert len(rgba) == 4 and rgba not in materials and rgba != background
        materials[rgba] = (m.find("Name").text.strip(), int(m.find("VoxelCount").text))

    # Layer names: PREFIX0.png .. PREFIX{n-1}.png, no padding, contiguous, nothing else of that form.
    names = sorted((n for n in job if re.fullmatch(re.escape(prefix) + r"\d+\.png", n)), key=lambda n: int(n[len(prefix):-4]))
    assert names == [f"{prefix}{i}.png" for i in range(layers)], f"layer names {names[:5]}... for {layers} layers"
    counts = {rgba: 0 for rgba in materials}
    for name in names:
        w, h, rows, phys = decode_png(job[name])
        assert (w, h) == (width, height), f"{name}: {w} x {h}, ConfigFile.xml says {width} x {height}"
        assert phys == (23622, 11811), f"{name}: pHYs {phys}"
        for row in rows:
            for i in range(0, len(row), 4):
                px = tuple(row[i:i + 4])
                if px == background:
                    continue
                assert px in counts, f"{name}: colour {px} is not in the material list"
                counts[px] += 1
    for rgba, (mname, listed) in materials.items():
        assert counts[rgba] == listed, f"{mname}: {counts[rgba]} pixels, VoxelCount {listed}"
    print(json.dumps({"layers": layers, "width": width, "height": height, "thickness_nm": nm,
                      "voxels": {n: c for (n, c) in materials.values()}}))


if __name__ == "__main__":
    main()
