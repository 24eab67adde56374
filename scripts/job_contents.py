#!/usr/bin/env python3
"""Do two print jobs (zip archives) hold the same contents, whatever their container bytes?

    scripts/job_contents.py NEW.zip REFERENCE.zip

Same contents means: the same entry names (in any order); every layer image, the build file and any
other entry the same bytes once decompressed; every PNG preview the same pixels (decoded by libpng
through ctypes, not by rodfab's code); report.html the same text once each embedded PNG (a data: URI) is
replaced by its decoded pixels; the manifest the same JSON apart from the sizes and checksums of the
previews and the report, which must instead describe each job's own files (size, and XXH3-128 when
`xxhsum` is installed).
An entry whose compressed bytes, method and CRC-32 equal the reference's is the same without being
inflated (equal deflate streams inflate to equal bytes). Prints one line a difference and exits 1 if
any; exits 0 and prints a summary otherwise, 2 on a usage or read error.
"""
import base64
import ctypes
import ctypes.util
import hashlib
import json
import re
import shutil
import struct
import subprocess
import sys
import zipfile

PNG_FORMAT_RGBA = 3  # PNG_FORMAT_FLAG_COLOR | PNG_FORMAT_FLAG_ALPHA: every PNG decoded to 8-bit RGBA


class PngImage(ctypes.Structure):  # libpng's simplified API (png.h, png_image)
    _fields_ = [("opaque", ctypes.c_void_p), ("version", ctypes.c_uint32), ("width", ctypes.c_uint32),
                ("height", ctypes.c_uint32), ("format", ctypes.c_uint32), ("flags", ctypes.c_uint32),
                ("colormap_entries", ctypes.c_uint32), ("warning_or_error", ctypes.c_uint32),
                ("message", ctypes.c_char * 64)]


_libpng = ctypes.CDLL(ctypes.util.find_library("png16") or "libpng16.so.16")
_libpng.png_image_begin_read_from_memory.argtypes = [ctypes.POINTER(PngImage), ctypes.c_void_p, ctypes.c_size_t]
_libpng.png_image_finish_read.argtypes = [ctypes.POINTER(PngImage), ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int32,
                                          ctypes.c_void_p]
_libpng.png_image_free.argtypes = [ctypes.POINTER(PngImage)]


def png_pixels(data):
    """(width, height, SHA-256 of the RGBA pixels) of a PNG file's bytes; raises ValueError if libpng cannot."""
    image = PngImage(version=1)
    buffer = ctypes.create_string_buffer(bytes(data), len(data))
    if not _libpng.png_image_begin_read_from_memory(ctypes.byref(image), buffer, len(data)):
        raise ValueError("libpng: " + image.message.decode(errors="replace"))
    image.format = PNG_FORMAT_RGBA
    pixels = ctypes.create_string_buffer(image.width * image.height * 4)
    if not _libpng.png_image_finish_read(ctypes.byref(image), None, pixels, 0, None):
        _libpng.png_image_free(ctypes.byref(image))
        raise ValueError("libpng: " + image.message.decode(errors="replace"))
    return image.width, image.height, hashlib.sha256(pixels.raw).hexdigest()


def raw_entry(archive, fp, info):
    """An entry's stored (compressed) bytes, read past its local header."""
    fp.seek(info.header_offset)
    header = fp.read(30)
    if header[:4] != b"PK\x03\x04":
        raise ValueError(info.filename + ": no local header at its offset")
    name_length, extra_length = struct.unpack("<HH", header[26:30])
    fp.seek(info.header_offset + 30 + name_length + extra_length)
    return fp.read(info.compress_size)


DATA_URI = re.compile(rb"data:image/png;base64,([A-Za-z0-9+/=]+)")


def report_text(data):
    """report.html with each embedded PNG replaced by its decoded pixels' description."""
    def pixels(match):
        w, h, digest = png_pixels(base64.b64decode(match.group(1)))
        return b"data:image/png;pixels,%dx%d,%s" % (w, h, digest.encode())
    return DATA_URI.sub(pixels, data)


def xxh128(data):
    """XXH3-128 as `xxhsum -H2` prints it, or None without xxhsum."""
    if not shutil.which("xxhsum"):
        return None
    out = subprocess.run(["xxhsum", "-H2", "-"], input=data, capture_output=True, check=True).stdout
    return out.split()[0].decode().split("_")[-1]


def manifest_without_rows(data, names, entries, problems, which):
    """The manifest's JSON without the sizes and checksums of `names` (each checked against `entries`)."""
    manifest = json.loads(data)
    files = manifest.get("files", {})
    for name in names:
        row = files.get(name)
        if row is None:
            problems.append("%s manifest: no row for %s" % (which, name))
            continue
        if row.get("bytes") != len(entries[name]):
            problems.append("%s manifest: %s bytes %s, the file has %d" % (which, name, row.get("bytes"), len(entries[name])))
        digest = xxh128(entries[name]) if "xxh128" in row else None
        if digest is not None and row["xxh128"] != digest:
            problems.append("%s manifest: %s xxh128 %s, the file's is %s" % (which, name, row["xxh128"], digest))
        for key in ("bytes", "xxh128", "sha256"):
            row.pop(key, None)
    return manifest


def compare(new_path, ref_path):
    problems, notes = [], []
    with zipfile.ZipFile(new_path) as new, zipfile.ZipFile(ref_path) as ref, open(new_path, "rb") as new_fp, \
            open(ref_path, "rb") as ref_fp:
        new_infos = {i.filename: i for i in new.infolist()}
        ref_infos = {i.filename: i for i in ref.infolist()}
        if set(new_infos) != set(ref_infos):
            only_new, only_ref = sorted(set(new_infos) - set(ref_infos)), sorted(set(ref_infos) - set(new_infos))
            problems.append("entry names differ: only in new %s, only in reference %s" % (only_new[:5], only_ref[:5]))
        if [i.filename for i in new.infolist()] != [i.filename for i in ref.infolist()]:
            notes.append("entry order differs")
        previews = sorted(n for n in new_infos if n.startswith("previews/") and n.endswith(".png"))
        small = {}  # manifest, report and previews of both, decompressed
        raw_same = inflated_same = 0
        for name in sorted(set(new_infos) & set(ref_infos)):
            a, b = new_infos[name], ref_infos[name]
            if name in ("manifest.json", "report.html") or name in previews:
                small[name] = (new.read(name), ref.read(name))
                continue
            if (a.compress_type, a.CRC, a.file_size) == (b.compress_type, b.CRC, b.file_size) and \
                    raw_entry(new, new_fp, a) == raw_entry(ref, ref_fp, b):
                raw_same += 1
            elif new.read(name) == ref.read(name):  # zipfile checks each entry's CRC-32 as it inflates
                inflated_same += 1
            else:
                problems.append(name + ": decompressed bytes differ")
        for name in previews:
            if name in small and png_pixels(small[name][0]) != png_pixels(small[name][1]):
                problems.append(name + ": decoded pixels differ")
        if "report.html" in small and report_text(small["report.html"][0]) != report_text(small["report.html"][1]):
            problems.append("report.html: differs beyond its embedded PNGs' encoding")
        if "manifest.json" in small:
            # The previews and the report (which embeds them) are compared by content above, so their
            # rows' sizes and checksums are checked against each job's own files instead.
            described = [n for n in previews + ["report.html"] if n in small]
            new_entries = {n: small[n][0] for n in described}
            ref_entries = {n: small[n][1] for n in described}
            m_new = manifest_without_rows(small["manifest.json"][0], described, new_entries, problems, "new")
            m_ref = manifest_without_rows(small["manifest.json"][1], described, ref_entries, problems, "reference")
            if m_new != m_ref:
                problems.append("manifest.json: differs beyond the sizes and checksums of the previews and the report")
    return problems, notes, raw_same, inflated_same, len(previews)


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    try:
        problems, notes, raw_same, inflated_same, previews = compare(sys.argv[1], sys.argv[2])
    except (OSError, ValueError, zipfile.BadZipFile, json.JSONDecodeError) as e:
        print("cannot compare: %s" % e, file=sys.stderr)
        return 2
    for p in problems:
        print(p)
    if problems:
        return 1
    print("same contents: %d entries with the same stored bytes, %d the same once inflated, %d previews by pixels%s"
          % (raw_same, inflated_same, previews, "; " + ", ".join(notes) if notes else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
