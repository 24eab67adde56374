#!/usr/bin/env python3
"""Makes hostile variants of a valid rodfab job for `rodfab inspect` tests, with Python's own zip and
zlib code (not rodfab's).

    hostile_jobs.py ZIP_JOB FOLDER_JOB OUT_DIR BOMB_MIB

writes into OUT_DIR:
  profile-stdin.zip   the manifest names /dev/stdin as its profile
  profile-zero.zip    ... /dev/zero
  bomb.zip            a BOMB_MIB MiB run of zeros deflated (~1000:1), listed in the manifest with its true
                      size and checksum, as an extra entry
  huge.zip            a layer whose headers declare 3.75 GiB
  dotdot.zip          an entry ../../x, listed in the manifest
  absolute.zip        an entry /tmp/x, listed in the manifest
  no-build.zip        no build file, and the manifest's file table without it
  no-rubbery.zip      every image of the rubbery material gone, and every mention of it in the manifest
  deep.zip            a manifest nested 60,000 levels deep
  hidden-entry.zip    the job as written, with a second local entry of one layer's name (another layer's
                      image) between two listed entries, which the central directory does not list: a
                      streaming unzipper unpacks it, a directory reader does not
  fifo/               the folder job with a FIFO in place of a layer
  zero-link/          the folder job with a link to /dev/zero in place of a layer
"""
import hashlib
import json
import os
import shutil
import struct
import sys
import zipfile
import zlib


def read_zip(path):
    with zipfile.ZipFile(path) as z:
        return [(i.filename, z.read(i)) for i in z.infolist()]


def write_zip(path, entries):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in entries:
            z.writestr(name, data)


def with_manifest(entries, change):
    manifest = json.loads(dict(entries)["manifest.json"])
    change(manifest)
    text = json.dumps(manifest, indent=1).encode()
    return [(n, text if n == "manifest.json" else d) for n, d in entries]


def listed(entries, name, data):
    def add(m):
        m["files"][name] = {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    return with_manifest(entries, add) + [(name, data)]


def raw_zip(path, entries):
    """entries: (name, stored bytes, method, crc, compressed size, size); headers written as told."""
    out, central = bytearray(), bytearray()
    for name, stored, method, crc, csize, size in entries:
        raw_name, offset = name.encode(), len(out)
        out += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, method, 0, 0x5021, crc, csize, size, len(raw_name), 0)
        out += raw_name + stored
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 0x031E, 20, 0, method, 0, 0x5021, crc, csize, size,
                               len(raw_name), 0, 0, 0, 0, 0o100644 << 16, offset) + raw_name
    directory = len(out)
    out += central + struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries), len(central), directory, 0)
    with open(path, "wb") as f:
        f.write(out)


def deflated(data):
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    return c.compress(data) + c.flush()


def zip_bombs(entries, out, mib):
    # The bomb as an extra entry, with its true size and checksum in the manifest (zip64 for the size).
    chunk, sha, crc = bytes(1 << 20), hashlib.sha256(), 0
    for _ in range(mib):
        sha.update(chunk)

    def add(m):
        m["files"]["bomb.bin"] = {"bytes": mib << 20, "sha256": sha.hexdigest()}
    with zipfile.ZipFile(os.path.join(out, "bomb.zip"), "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        for name, data in with_manifest(entries, add):
            z.writestr(name, data)
        with z.open("bomb.bin", "w", force_zip64=True) as w:
            for _ in range(mib):
                w.write(chunk)
    # A layer whose headers declare 3.75 GiB.
    layer = next(n for n, _ in entries if n.startswith("VeroWhitePlus_"))
    raw = []
    for name, data in entries:
        stored = deflated(data)
        size = 0xF0000000 if name == layer else len(data)
        raw.append((name, stored, 8, zlib.crc32(data), len(stored), size))
    raw_zip(os.path.join(out, "huge.zip"), raw)


def zip_variants(entries, out):
    for name, profile in (("profile-stdin.zip", "/dev/stdin"), ("profile-zero.zip", "/dev/zero")):
        write_zip(os.path.join(out, name), with_manifest(entries, lambda m, p=profile: m["profile"].update(name=p)))
    write_zip(os.path.join(out, "dotdot.zip"), listed(entries, "../../x", b"outside"))
    write_zip(os.path.join(out, "absolute.zip"), listed(entries, "/tmp/x", b"outside"))
    build = [(n, d) for n, d in entries if n != "build.txt"]
    write_zip(os.path.join(out, "no-build.zip"), with_manifest(build, lambda m: m["files"].pop("build.txt")))

    rubbery = next(m["name"] for m in json.loads(dict(entries)["manifest.json"])["materials"] if m["role"] == "rubbery")

    def drop_rubbery(m):
        m["materials"] = [x for x in m["materials"] if x["name"] != rubbery]
        m["files"] = {k: v for k, v in m["files"].items() if not k.startswith(rubbery + "_")}
        for layer in m["layers"]:
            layer["files"].pop(rubbery)
            layer["voxels"].pop(rubbery)
        m["orientation_check"].pop(rubbery, None)
    kept = [(n, d) for n, d in entries if not n.startswith(rubbery + "_")]
    write_zip(os.path.join(out, "no-rubbery.zip"), with_manifest(kept, drop_rubbery))
    deep = b"[" * 60000 + b"]" * 60000
    write_zip(os.path.join(out, "deep.zip"), [(n, deep if n == "manifest.json" else d) for n, d in entries])


def folder_variants(folder, out):
    layer = sorted(n for n in os.listdir(folder) if n.startswith("VeroWhitePlus_"))[1]
    for name in ("fifo", "zero-link"):
        target = os.path.join(out, name)
        shutil.copytree(folder, target)
        os.remove(os.path.join(target, layer))
        if name == "fifo":
            os.mkfifo(os.path.join(target, layer))
        else:
            os.symlink("/dev/zero", os.path.join(target, layer))


def hidden_local_entry(zip_job, out):
    """Inserts, after the first layer image's local record, a local record of that name holding the same
    material's last layer image, and moves every later offset of the central directory (and the directory's own) along."""
    data = bytearray(open(zip_job, "rb").read())
    with zipfile.ZipFile(zip_job) as z:
        infos = sorted(z.infolist(), key=lambda i: i.header_offset)
    layers = [i for i in infos if i.filename.endswith(".bmp")]
    first = layers[0]
    last = [i for i in layers if i.filename.rsplit("_", 1)[0] == first.filename.rsplit("_", 1)[0]][-1]  # same material

    def record(info):  # local header, name, extra and data as they lie in the file
        name_len, extra_len = struct.unpack("<HH", data[info.header_offset + 26:info.header_offset + 30])
        return bytes(data[info.header_offset:info.header_offset + 30 + name_len + extra_len + info.compress_size])
    if len(first.filename) != len(last.filename):
        raise SystemExit("hidden-entry.zip: layer names of different lengths")
    hidden = bytearray(record(last))
    hidden[30:30 + len(first.filename)] = first.filename.encode()
    at = first.header_offset + len(record(first))
    data[at:at] = hidden
    end = data.rfind(b"PK\x05\x06")
    directory = struct.unpack("<I", data[end + 16:end + 20])[0]
    struct.pack_into("<I", data, end + 16, directory + len(hidden))
    p = directory + len(hidden)
    while data[p:p + 4] == b"PK\x01\x02":
        offset = struct.unpack("<I", data[p + 42:p + 46])[0]
        if offset >= at:
            struct.pack_into("<I", data, p + 42, offset + len(hidden))
        n, m, k = struct.unpack("<HHH", data[p + 28:p + 34])
        p += 46 + n + m + k
    with open(os.path.join(out, "hidden-entry.zip"), "wb") as f:
        f.write(data)
    with zipfile.ZipFile(os.path.join(out, "hidden-entry.zip")) as z:  # still a sound zip to a directory reader
        if z.testzip() is not None:
            raise SystemExit("hidden-entry.zip: its listed entries do not read back")


def main():
    zip_job, folder_job, out, mib = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    os.makedirs(out, exist_ok=True)
    entries = read_zip(zip_job)
    zip_variants(entries, out)
    zip_bombs(entries, out, mib)
    hidden_local_entry(zip_job, out)
    folder_variants(folder_job, out)


if __name__ == "__main__":
    main()
