#!/usr/bin/env python3
"""report.html in a job: self-contained, rendered by headless Chromium, its figures those of the job.

    report.py RODFAB SOURCE_DIR CHROMIUM

Slices the unfolding box with one rod asking for less than the calibration floor and one for more than
the stiffest mix, then checks the report against the manifest and the job's files (parsed here, not by
rodfab): every picture embedded (the previews byte for byte), nothing fetched from the network; and, in
the page Chromium renders, the layer count, print height, per-material voxels, volume and mass, the
clamped-moduli counts (also as located by the picture), the calibration's name and SHA-256 (hashed
here), the ditherer and the checksums' verdict. A screenshot must show a page, not a blank.
"""
import base64
import hashlib
import html
import html.parser
import json
import os
import pathlib
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zipfile
import zlib

rodfab, src, chromium = sys.argv[1], pathlib.Path(sys.argv[2]), sys.argv[3]
if not shutil.which(chromium):
    sys.exit(f"FAIL: {chromium} not found: install Debian's chromium (scripts/install-deps.sh) to test the job report")
failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
        print("FAIL:", message)


class Page(html.parser.HTMLParser):
    """Text by element id, material rows by data-material, image sources."""

    def __init__(self):
        super().__init__()
        self.by_id, self.materials, self.images, self.links = {}, {}, [], []
        self.stack = []  # (tag, id, class) of open elements
        self.material = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.images.append(a)
            return
        if tag in ("a", "link", "script", "iframe", "object", "embed", "base"):
            self.links.append((tag, a))
        if tag == "tr" and "data-material" in a:
            self.material = a["data-material"]
            self.materials[self.material] = {}
        self.stack.append((tag, a.get("id"), a.get("class", "")))
        if a.get("id"):
            self.by_id[a["id"]] = ""

    def handle_endtag(self, tag):
        while self.stack:
            t, _, _ = self.stack.pop()
            if t == tag:
                break
        if tag == "tr":
            self.material = None

    def handle_data(self, data):
        for _, ident, cls in self.stack:
            if ident:
                self.by_id[ident] += data
            if self.material and cls:
                for c in cls.split():
                    self.materials[self.material][c] = self.materials[self.material].get(c, "") + data


def png_pixels(data):
    """(width, height, rows of RGB(A) bytes) of an 8-bit RGB or RGBA PNG, decoded here."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour = header[:4]
    assert depth == 8 and colour in (2, 6), f"unexpected PNG depth {depth} colour {colour}"
    bpp = 3 if colour == 2 else 4
    raw, stride, rows, prev = zlib.decompress(idat), width * bpp, [], bytearray(width * bpp)
    for y in range(height):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b, c = prev[x], prev[x - bpp] if x >= bpp else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    return width, height, bpp, rows


def chromium_run(args, tmp):
    profile = tempfile.mkdtemp(dir=tmp)
    command = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               f"--user-data-dir={profile}"] + args
    return subprocess.run(command, capture_output=True, timeout=120)


with tempfile.TemporaryDirectory() as tmp:
    tmp = pathlib.Path(tmp)
    design = json.loads((src / "examples" / "unfolding-box.json").read_text())
    design["rods"][0]["modulus"] = 3.0    # below the bundled calibration's 8 MPa floor
    design["rods"][1]["modulus"] = 400.0  # above its 190 MPa stiffest mix
    (tmp / "clamped.json").write_text(json.dumps(design))
    run = subprocess.run([rodfab, "slice", str(tmp / "clamped.json"), "-o", str(tmp / "job.zip"), "--quiet"],
                         capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"FAIL: slice: {run.stderr}")
    job = zipfile.ZipFile(tmp / "job.zip")
    manifest = json.loads(job.read("manifest.json"))
    check(manifest.get("report") == "report.html", "the manifest names report.html")
    report = job.read("report.html")
    xxh = subprocess.run(["xxhsum", "-H2", "-"], input=report, capture_output=True, check=True).stdout.split()[0].decode()
    check(xxh == manifest["files"]["report.html"]["xxh128"], "report.html matches its checksum (xxhsum -H2)")
    (tmp / "report.html").write_bytes(report)
    print(f"report.html: {len(report)} bytes")

    # Self-contained: every picture a data: URI (the previews exactly the job's), nothing to fetch.
    static = Page()
    static.feed(report.decode("utf-8"))
    check(not static.links, f"no links, scripts or frames: {static.links}")
    check(not re.search(rb"(?i)(https?:|url\(|@import|<script)", report), "nothing that could reach the network")
    sources = [img.get("src", "") for img in static.images]
    check(all(s.startswith("data:image/png;base64,") for s in sources), "every image is an embedded PNG")
    embedded = {img.get("data-file"): base64.b64decode(img["src"].split(",", 1)[1]) for img in static.images}
    for name in manifest["previews"]:
        check(embedded.get(name) == job.read(name), f"{name} embedded byte for byte")
    check(len(sources) == len(manifest["previews"]) + 2, "previews, the clamped-voxels picture and the calibration plot")

    # What Chromium renders.
    start = time.monotonic()
    dom = chromium_run(["--dump-dom", (tmp / "report.html").as_uri()], tmp)
    shot = chromium_run(["--window-size=1200,2400", f"--screenshot={tmp / 'shot.png'}", (tmp / "report.html").as_uri()], tmp)
    print(f"chromium: {time.monotonic() - start:.1f} s for the DOM and the screenshot")
    check(dom.returncode == 0 and shot.returncode == 0, f"chromium ran: {dom.stderr[-300:]!r} {shot.stderr[-300:]!r}")
    page = Page()
    page.feed(dom.stdout.decode("utf-8"))
    text = page.by_id
    number = lambda s: int(s.replace(",", "").split()[0])

    layers = manifest["layer_count"]
    thickness = manifest["profile"]["layer_thickness_mm"]
    check(number(text.get("layer-count", "0")) == layers, f"layer count {layers}: {text.get('layer-count')!r}")
    check(text.get("print-height") == f"{layers * thickness:.2f} mm", f"print height: {text.get('print-height')!r}")
    stats = manifest["statistics"]
    check(number(text.get("model-voxels", "0")) == stats["model_voxels"], "model voxels")
    for name, s in stats["materials"].items():
        row = page.materials.get(name, {})
        check(number(row.get("voxels", "0")) == s["voxels"], f"{name} voxels: {row}")
        check(row.get("volume") == f"{s['volume_ml']:.3f} mL", f"{name} volume {s['volume_ml']}: {row.get('volume')!r}")
        check(row.get("mass") == f"{s['mass_g']:.3f} g", f"{name} mass {s['mass_g']}: {row.get('mass')!r}")
    total_mass = sum(s["mass_g"] for s in stats["materials"].values())
    check(text.get("total-mass") == f"{total_mass:.3f} g", f"total mass: {text.get('total-mass')!r}")

    clamped = stats["clamped_modulus"]
    below, above = clamped["below_floor_voxels"], clamped["above_ceiling_voxels"]
    check(below > 0 and above > 0, f"the design has clamped voxels both ways: {clamped}")
    check(number(text.get("clamped-below", "0")) == below, f"clamped below: {text.get('clamped-below')!r} vs {below}")
    check(number(text.get("clamped-above", "0")) == above, f"clamped above: {text.get('clamped-above')!r} vs {above}")
    # The picture's own count (voxels located band by band) agrees with the mapping's.
    check(number(text.get("located-below", "0")) == below, f"located below: {text.get('located-below')!r} vs {below}")
    check(number(text.get("located-above", "0")) == above, f"located above: {text.get('located-above')!r} vs {above}")

    bundled = hashlib.sha256((src / "examples" / "calibration" / "default-60C.json").read_bytes()).hexdigest()
    check(text.get("calibration-file") == "default-60C.json", f"calibration file: {text.get('calibration-file')!r}")
    check(text.get("calibration-sha256") == bundled == manifest["calibration"]["sha256"], "calibration SHA-256")
    check(text.get("ditherer") == manifest["dithering"]["ditherer"], "ditherer")
    check(text.get("seed") == str(manifest["dithering"]["seed"]), "seed")
    check(text.get("checksum-verdict", "").startswith("Verified when written"), "the checksums' verdict")
    check(text.get("design") == "clamped.json", f"the design by name: {text.get('design')!r}")

    # The screenshot shows a page with pictures: coloured pixels (the verdict box, the previews), and
    # much that is not white (a page whose images failed to load is mostly white).
    width, height, bpp, rows = png_pixels((tmp / "shot.png").read_bytes())
    check((width, height) == (1200, 2400), f"screenshot size {width} x {height}")
    samples = [row[x:x + 3] for row in rows[::4] for x in range(0, width * bpp, 4 * bpp)]
    coloured = sum(1 for p in samples if max(p) - min(p) > 40)
    drawn = sum(1 for p in samples if min(p) < 235)
    print(f"screenshot: {coloured} coloured and {drawn} non-white samples of {len(samples)}")
    check(coloured > 500 and drawn > len(samples) // 5, "the screenshot shows the pictures")

    # inspect accepts the job with its report, and notices a changed report.
    check(subprocess.run([rodfab, "inspect", str(tmp / "job.zip")], capture_output=True).returncode == 0, "inspect passes")
    subprocess.run([rodfab, "slice", str(tmp / "clamped.json"), "-o", str(tmp / "dir"), "--format", "dir", "--quiet"], check=True)
    with open(tmp / "dir" / "report.html", "r+b") as f:
        f.seek(100)
        f.write(b"X")
    bad = subprocess.run([rodfab, "inspect", str(tmp / "dir")], capture_output=True, text=True)
    check(bad.returncode != 0 and "report.html" in bad.stdout + bad.stderr, f"inspect names a changed report: {bad.stdout[-400:]}")

    # Coupon jobs have a report too (no calibration or clamping recorded).
    subprocess.run([rodfab, "coupons", "-o", str(tmp / "coupons.zip"), "--fractions", "0,1", "--quiet"], check=True,
                   capture_output=True)
    coupons = zipfile.ZipFile(tmp / "coupons.zip")
    check(json.loads(coupons.read("manifest.json")).get("report") == "report.html", "a coupon job names its report")
    check(b"<h1>Job report</h1>" in coupons.read("report.html"), "a coupon job's report")
    check(subprocess.run([rodfab, "inspect", str(tmp / "coupons.zip")], capture_output=True).returncode == 0,
          "inspect passes the coupon job")

    # Every warning slice says on stderr is in the report too (a J750 job on the stand-in calibration,
    # dithered otherwise than its coupons: the report said "None").
    run = subprocess.run([rodfab, "slice", str(tmp / "clamped.json"), "-o", str(tmp / "j750.zip"), "--profile",
                          "stratasys-j750-j850", "--dither", "blue", "--quiet"], capture_output=True, text=True)
    said = [line.split("warning: ", 1)[1] for line in run.stderr.splitlines() if line.startswith("rodfab slice: warning: ")]
    section = re.search(r'<section id="warnings">(.*?)</section>', zipfile.ZipFile(tmp / "j750.zip").read("report.html").decode(), re.S)
    listed = [html.unescape(item) for item in re.findall(r"<li>(.*?)</li>", section.group(1) if section else "", re.S)]
    check(run.returncode == 0 and len(said) >= 2, f"the J750 job warns of its calibration and ditherer: {run.stderr[-400:]!r}")
    check(sorted(said) == sorted(listed), f"the report lists what slice warned: said {said}, listed {listed}")

if failures:
    sys.exit(f"{len(failures)} check(s) failed")
print("report: all checks passed")
