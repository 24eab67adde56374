"""Layer images compressed by igzip, read by decoders that share nothing with rodfab's writer: python's
zipfile and zlib (zip CRCs, raw deflate, PNG's zlib stream and Adler-32), the BMP and PNG formats
decoded here from their specifications. For BMP and 1-bit PNG Connex3 jobs and a J750 .gcvf: every
layer decodes to the voxel counts the manifest lists, every file's XXH3-128 in the manifest is what xxhsum
(Debian `xxhash`) computes, and the
bytes are the same for 1 and 2 threads and other band sizes; a sparse job's blank images (made once and
shared by the writer) as well, and the same as a folder job's files.

    emit_decoders.py RODFAB SOURCE_DIR
"""

import array
import collections
import json
import os
import struct
import subprocess
import sys
import tempfile
import zipfile
import zlib

rodfab, src = sys.argv[1], sys.argv[2]
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gcvf_decode import decode_png as decode_rgba_png  # noqa: E402  (the gcvf test's own reader)

DESIGN = os.path.join(src, "examples", "unfolding-box.json")
ROD = {"format": "rodfab.design/1", "units": "mm", "rods": [{"name": "edge-0",
       "centerline": {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "points": [[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0]]},
       "section": {"shape": "circle", "diameter": 1.5}, "normal": [0, 0, 1],
       "modulus": {"degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [8, 120, 40]}}]}


# Two short rods 6 mm apart in z: most of the job's 200-odd layers hold no voxel, and the stiff rod's
# layers (E above the stiffest mix: all Vero) none of the rubbery material. Such blank images are
# hashed and deflated once a job and shared (printer_profiles' keepBlank).
SPARSE = {"format": "rodfab.design/1", "units": "mm", "rods": [
    {"name": name, "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, z], [3, 0, z]]},
     "section": {"shape": "circle", "diameter": 0.8}, "normal": [0, 0, 1],
     "modulus": {"degree": 1, "knots": [0, 0, 1, 1], "values": [e, e]}}
    for name, z, e in (("stiff", 0.0, 400.0), ("soft", 6.0, 30.0))]}


def fail(message):
    print("FAIL:", message)
    sys.exit(1)


def slice_job(design, out, *args):
    r = subprocess.run([rodfab, "slice", design, "-o", out, "--quiet", *args], capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"slice {' '.join(args)}: {r.stderr}")


def bmp_set_bits(data):
    assert data[:2] == b"BM", "not a BMP"
    offset, = struct.unpack_from("<I", data, 10)
    width, height, planes, bpp, compression = struct.unpack_from("<iiHHI", data, 18)
    assert (planes, bpp, compression) == (1, 1, 0), (planes, bpp, compression)
    stride = (width + 31) // 32 * 4
    count = 0
    for r in range(abs(height)):
        row = data[offset + r * stride: offset + (r + 1) * stride]
        count += sum(bin(b).count("1") for b in row[: (width + 7) // 8])  # the writer keeps padding bits clear
    return count


def png_chunks(data):
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, chunks = 8, []
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        crc, = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"bad CRC in {kind}"
        chunks.append((kind, body))
        pos += 12 + length
    assert chunks[0][0] == b"IHDR" and chunks[-1] == (b"IEND", b""), [c[0] for c in chunks]
    return chunks


def png1_set_bits(data):
    chunks = png_chunks(data)
    width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    assert (depth, colour, interlace) == (1, 0, 0), (depth, colour, interlace)
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))  # checks Adler-32
    stride = (width + 7) // 8
    assert len(raw) == height * (stride + 1)
    count = 0
    for r in range(height):
        assert raw[r * (stride + 1)] == 0, "row filter other than None"  # 1-bit rows: the writer uses none
        count += sum(bin(b).count("1") for b in raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
    return count


def check_zip(path, method):
    with zipfile.ZipFile(path) as z:
        if z.testzip() is not None:
            fail(f"{path}: zlib finds a bad CRC in {z.testzip()}")
        manifest = json.loads(z.read("manifest.json"))
        files = {i.filename: i for i in z.infolist()}
        layers = 0
        for layer in manifest["layers"]:
            for material, name in layer["files"].items():
                info = files[name]
                if info.compress_type != method:
                    fail(f"{name}: zip method {info.compress_type}, expected {method}")
                data = z.read(name)
                if name.endswith(".bmp"):
                    got = bmp_set_bits(data)
                elif manifest["image"]["bit_depth"] == 1:
                    got = png1_set_bits(data)
                else:
                    continue  # RGBA: counted below
                if got != layer["voxels"][material]:
                    fail(f"{name}: {got} pixels set, the manifest lists {layer['voxels'][material]}")
            layers += 1
        check_file_table(z, manifest)
        return manifest, layers


def check_file_table(z, manifest):
    """xxhsum checks every file the manifest lists against its "xxh128" (32 hex digits: XXH3-128)."""
    with tempfile.TemporaryDirectory() as tmp:
        lines = []
        for name, row in manifest["files"].items():
            if set(row) != {"bytes", "xxh128"} or len(row["xxh128"]) != 32:
                fail(f"{name}: manifest row {row}, expected bytes and a 32-digit xxh128")
            path = os.path.join(tmp, name)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "wb") as f:
                f.write(z.read(name))
            lines.append(f"{row['xxh128']}  {name}\n")
        with open(os.path.join(tmp, "sums"), "w") as f:
            f.writelines(lines)
        run = subprocess.run(["xxhsum", "-c", "--quiet", "sums"], cwd=tmp, capture_output=True, text=True)
        if run.returncode != 0:
            fail(f"xxhsum disagrees with the manifest: {run.stdout[-2000:]} {run.stderr[-2000:]}")


def rgba_model_pixels(data):
    """Pixels that are not the most common colour (the background) of an unfiltered 8-bit RGBA PNG: the
    writer's layers use filter None, so the inflated rows are the pixels (large layers, fast in python)."""
    chunks = png_chunks(data)
    width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    assert (depth, colour, interlace) == (8, 6, 0)
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    line = 4 * width + 1
    assert len(raw) == height * line
    counts = collections.Counter()
    for r in range(height):
        assert raw[r * line] == 0, "row filter other than None"
        counts.update(array.array("I", raw[r * line + 1:(r + 1) * line]))
    return width * height - max(counts.values())


def check_large_gcvf(path, every):
    """A layer larger than the writer's 1 MB batch: compressed by igzip in pieces (DeflateStream)."""
    with zipfile.ZipFile(path) as z:
        if z.testzip() is not None:
            fail(f"{path}: zlib finds a bad CRC")
        manifest = json.loads(z.read("manifest.json"))
        assert manifest["image"]["width"] * 4 * manifest["image"]["height"] > 1 << 20
        for layer in manifest["layers"][::every]:
            name = next(iter(layer["files"].values()))
            got, model = rgba_model_pixels(z.read(name)), sum(layer["voxels"].values())
            if got != model:
                fail(f"{name}: {got} model pixels, the manifest lists {model}")


def check_gcvf(path):
    with zipfile.ZipFile(path) as z:
        if z.testzip() is not None:
            fail(f"{path}: zlib finds a bad CRC")
        manifest = json.loads(z.read("manifest.json"))
        for layer in manifest["layers"]:
            name = next(iter(layer["files"].values()))
            data = z.read(name)
            png_chunks(data)
            width, height, rows, _ = decode_rgba_png(data)
            pixels = {}
            for row in rows:
                for x in range(0, len(row), 4):
                    pixels[row[x:x + 4]] = pixels.get(row[x:x + 4], 0) + 1
            model = sum(layer["voxels"].values())
            if width * height - max(pixels.values()) != model:  # the background is the most common colour
                fail(f"{name}: {width * height - max(pixels.values())} model pixels, the manifest lists {model}")
        return manifest


def check_blank_layers(tmp):
    """Blank images (shared by the writer) decode, checksum and CRC like the others, equal a folder job's
    files and a one-thread job's bytes, and are the BMP of a layer with its pixels all clear."""
    sparse = os.path.join(tmp, "sparse.json")
    json.dump(SPARSE, open(sparse, "w"))
    for form, extra, method in [("bmp", [], zipfile.ZIP_DEFLATED), ("png", ["--image-format", "png"], zipfile.ZIP_STORED)]:
        one, two = os.path.join(tmp, "1", f"sparse-{form}.zip"), os.path.join(tmp, "2", f"sparse-{form}.zip")
        folder = os.path.join(tmp, f"sparse-{form}")
        slice_job(sparse, one, "--threads", "1", *extra)
        slice_job(sparse, two, "--threads", "2", "--band-layers", "5", *extra)
        slice_job(sparse, folder, "--format", "dir", *extra)
        if open(one, "rb").read() != open(two, "rb").read():
            fail(f"sparse {form}: the jobs differ between 1 thread and 2 threads with 5-layer bands")
        manifest, layers = check_zip(one, method)
        blank = [(layer, m) for layer in manifest["layers"] for m, n in layer["voxels"].items() if n == 0]
        full = [layer for layer in manifest["layers"] if all(n > 0 for n in layer["voxels"].values())]
        one_blank = [layer for layer in manifest["layers"] if sorted(layer["voxels"].values())[0] == 0 < sum(layer["voxels"].values())]
        if len(blank) < layers or not full or not one_blank:
            fail(f"sparse {form}: {len(blank)} blank images of {layers} layers, {len(full)} with both materials, "
                 f"{len(one_blank)} with one: not the mix this test needs")
        with zipfile.ZipFile(one) as z:
            for layer in manifest["layers"]:
                for material, name in layer["files"].items():
                    data = z.read(name)
                    if data != open(os.path.join(folder, name), "rb").read():
                        fail(f"sparse {form}: {name} differs between the zip and the folder job")
            for layer, material in blank:
                data = z.read(layer["files"][material])
                if form == "bmp":
                    offset, = struct.unpack_from("<I", data, 10)
                    if data[offset:] != bytes(len(data) - offset):
                        fail(f"{layer['files'][material]}: a blank layer with pixel bytes set")
        print(f"sparse {form}: {len(blank)} blank images of {layers} layers decoded, as the folder job's files")





def rewritten(job, out, odd, level, contents_of=None):
    """`job` written again by python's zipfile (zlib level 6), entry `odd` at `level` (with the contents of
    entry `contents_of` when given)."""
    with zipfile.ZipFile(job) as src, zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            data = src.read(contents_of if info.filename == odd and contents_of else info.filename)
            copy = zipfile.ZipInfo(info.filename, info.date_time)
            copy.compress_type = info.compress_type
            dst.writestr(copy, data, compresslevel=level if info.filename == odd else 6)


def inspect_json(job):
    run = subprocess.run([rodfab, "inspect", job, "--json"], capture_output=True, text=True)
    return json.loads(run.stdout)


def check_inspect_blank_copies(tmp):
    """inspect reads a copy of a blank image it has checked and decoded as the zip stores it, when its stored
    bytes are the checked one's: a sparse job's blank images (one contents for both materials) all but the
    first; a copy deflated otherwise is decoded in full; a copy with other contents is a checksum mismatch."""
    job = os.path.join(tmp, "1", "sparse-bmp.zip")
    with zipfile.ZipFile(job) as z:
        manifest = json.loads(z.read("manifest.json"))
    blank = [layer["files"][m] for layer in manifest["layers"] for m, n in layer["voxels"].items() if n == 0]
    full = [layer["files"][m] for layer in manifest["layers"] for m, n in layer["voxels"].items() if n > 0]
    report = inspect_json(job)
    if not report["ok"] or report["blank_copies_compared_stored"] != len(blank) - 1:
        fail(f"inspect of the sparse job: ok {report['ok']}, {report['blank_copies_compared_stored']} blank copies compared "
             f"as stored of {len(blank)} blank images: {report['defects']}")
    odd = blank[len(blank) // 2]
    relevel, swapped = os.path.join(tmp, "relevel.zip"), os.path.join(tmp, "swapped.zip")
    rewritten(job, relevel, odd, 1)
    report = inspect_json(relevel)
    if not report["ok"] or report["blank_copies_compared_stored"] != len(blank) - 2:
        fail(f"inspect with {odd} deflated at another level: ok {report['ok']}, {report['blank_copies_compared_stored']} "
             f"copies compared as stored (expected {len(blank) - 2}): {report['defects']}")
    rewritten(job, swapped, odd, 6, full[0])
    report = inspect_json(swapped)
    if report["ok"] or not any(odd in d and "checksum mismatch" in d for d in report["defects"]):
        fail(f"inspect with {odd} holding {full[0]}'s image: {report['defects']}")
    print(f"inspect: {len(blank) - 1} blank copies compared as stored; one deflated otherwise decoded; one changed found")


with tempfile.TemporaryDirectory() as tmp:
    # The job's name is in its manifest and report: the compared jobs have the same name in two folders.
    for folder in ("1", "2"):
        os.mkdir(os.path.join(tmp, folder))
    rod = os.path.join(tmp, "rod.json")
    json.dump(ROD, open(rod, "w"))
    for form, design, extra, method in [("bmp", DESIGN, [], zipfile.ZIP_DEFLATED),
                                        ("png", DESIGN, ["--image-format", "png"], zipfile.ZIP_STORED)]:
        one, two = os.path.join(tmp, "1", f"{form}.zip"), os.path.join(tmp, "2", f"{form}.zip")
        slice_job(design, one, "--threads", "1", *extra)
        slice_job(design, two, "--threads", "2", "--band-layers", "7", *extra)
        if open(one, "rb").read() != open(two, "rb").read():
            fail(f"{form}: the jobs differ between 1 thread and 2 threads with 7-layer bands")
        manifest, layers = check_zip(one, method)
        print(f"{form}: {layers} layers decoded by zipfile/zlib, counts and SHA-256 as listed")
    check_blank_layers(tmp)
    check_inspect_blank_copies(tmp)
    one, two = os.path.join(tmp, "1", "rod.gcvf"), os.path.join(tmp, "2", "rod.gcvf")
    slice_job(rod, one, "--profile", "stratasys-j750-j850", "--threads", "1")
    slice_job(rod, two, "--profile", "stratasys-j750-j850", "--threads", "2", "--band-layers", "5")
    if open(one, "rb").read() != open(two, "rb").read():
        fail("gcvf: the jobs differ between 1 thread and 2 threads with 5-layer bands")
    check_gcvf(one)
    print("gcvf: every RGBA layer decoded by zlib, model pixels as listed")
    one, two = os.path.join(tmp, "1", "box.gcvf"), os.path.join(tmp, "2", "box.gcvf")
    slice_job(DESIGN, one, "--profile", "stratasys-j750-j850", "--threads", "1")
    slice_job(DESIGN, two, "--profile", "stratasys-j750-j850", "--threads", "2", "--band-layers", "9")
    if open(one, "rb").read() != open(two, "rb").read():
        fail("large gcvf: the jobs differ between 1 thread and 2 threads with 9-layer bands")
    check_large_gcvf(one, 5)
    print("large gcvf: layers compressed in pieces decoded by zlib, model pixels as listed")
print("ok")
