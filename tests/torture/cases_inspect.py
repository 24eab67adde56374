"""Class 6, hostile jobs for `rodfab inspect`: real jobs (sliced by the binary under test) with a
manifest naming devices or FIFOs, FIFOs and device links among the files, zip entries that declare
gigabytes or inflate to them, names that climb out of the job, missing files and absurd numbers.
Each must fail (exit 1) with the job or entry named, within bounded memory and without hanging."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from engine import MiB, Case, Step
from fixtures import Entry, bomb, fifo, manifest_entry, remove_material, tampered_dir, tampered_zip, write_zip

RSS = 256 * MiB  # a correct inspect of these small jobs needs ~50 MB; reading a declared size would need GBs


# A defect is located when it names the job, the manifest or one of the job's files.
JOB_PARTS = ["manifest", "VeroWhitePlus", "TangoBlackPlus", "build.txt", "previews/"]


def defective(name: str, job: str, build, note: str, where: list[str] = (), expect=frozenset({1}), files=None,
              timeout: float = 15) -> Case:
    return Case(name, [Step(["inspect", job], expect=set(expect), where=[job, *JOB_PARTS, *where], rss_limit=RSS,
                            timeout=timeout)],
                files={**(files or {}), job: build}, note=note)


def set_path(manifest: dict, path: list, value) -> None:
    node = manifest
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value


def first_image(manifest: dict, material: str = "VeroWhitePlus") -> str:
    return sorted(n for n in manifest["files"] if n.startswith(material + "_"))[0]


def cases(ctx) -> list[Case]:
    cs: list[Case] = []

    # Manifest fields that name paths: the profile (inspect looks the bundled one up by name).
    for tag, value in [("dev-zero", "/dev/zero"), ("dev-stdin", "/dev/stdin"), ("dev-urandom", "/dev/urandom"),
                       ("proc-self-fd0", "/proc/self/fd/0"), ("relative-dev-zero", "../../../../../../../../dev/zero")]:
        cs.append(defective(f"profile-name-{tag}-dir", "bad-job",
                            tampered_dir(lambda p, m, v=value: set_path(m, ["profile", "name"], v)),
                            f"manifest profile.name = {value}", ["profile"]))
        cs.append(defective(f"profile-name-{tag}-zip", "bad-job.zip",
                            tampered_zip(lambda e, m, v=value: set_path(m, ["profile", "name"], v)),
                            f"manifest profile.name = {value} in a zip", ["profile"]))

    def profile_fifo(p: Path, m: dict) -> None:
        os.mkfifo(p.parent / "profile.fifo")
        set_path(m, ["profile", "name"], str(p.parent / "profile.fifo"))
    cs.append(defective("profile-name-fifo", "bad-job", tampered_dir(profile_fifo), "manifest profile.name = a FIFO", ["profile"]))

    # Special files in a folder job, in place of listed files.
    def replace_with(kind: str, which: str):
        def mutate(p: Path, m: dict) -> None:
            target = p / (first_image(m) if which == "image" else which)
            if target.is_dir():
                shutil.rmtree(target)
            else:
                target.unlink()
            if kind == "fifo":
                os.mkfifo(target)
            elif kind == "dir":
                target.mkdir()
            elif kind == "loop":
                os.symlink(target.name, target)
            else:
                os.symlink(kind, target)
        return mutate

    for which in ["image", "build.txt", "previews/contact-sheet.png"]:
        for kind in ["fifo", "/dev/zero", "/dev/urandom", "/dev/stdin", "dir", "loop"]:
            tag = kind.strip("/").replace("/", "-")
            cs.append(defective(f"{tag}-as-{which.replace('/', '-')}", "bad-job", tampered_dir(replace_with(kind, which)),
                                f"a {kind} in place of {which}"))
    cs.append(defective("fifo-as-manifest", "bad-job", tampered_dir(replace_with("fifo", "manifest.json"), rewrite_manifest=False),
                        "manifest.json is a FIFO", ["manifest.json"]))
    cs.append(defective("dev-zero-as-manifest", "bad-job",
                        tampered_dir(replace_with("/dev/zero", "manifest.json"), rewrite_manifest=False),
                        "manifest.json links to /dev/zero", ["manifest.json"]))
    cs.append(defective("job-is-fifo", "job.zip", fifo, "the job itself is a FIFO"))
    cs.append(Case("job-is-dev-stdin", [Step(["inspect", "/dev/stdin"], expect={1}, where=["/dev/stdin"], rss_limit=RSS)],
                   note="inspect /dev/stdin (a pipe that never ends)"))
    cs.append(Case("job-is-dev-zero", [Step(["inspect", "/dev/zero"], expect={1}, where=["/dev/zero"], rss_limit=RSS)],
                   note="inspect /dev/zero"))

    # Zip entries that lie about their size, or inflate without end.
    def declared(size: int, name_of=first_image):
        def mutate(entries: list[Entry], m: dict):
            victim = name_of(m)
            for e in entries:
                if e.name == victim:
                    e.size = size
        return mutate

    cs.append(defective("zip-entry-declares-3.75GiB", "bad-job.zip", tampered_zip(declared(0xF0000000)),
                        "an image entry declaring 3.75 GiB uncompressed"))
    cs.append(defective("zip-manifest-declares-3.75GiB", "bad-job.zip",
                        tampered_zip(lambda e, m: [Entry("manifest.json", json.dumps(m).encode(), size=0xF0000000)] + e),
                        "manifest.json declaring 3.75 GiB", ["manifest.json"]))
    cs.append(defective("zip-build-file-declares-4GiB", "bad-job.zip", tampered_zip(declared(0xFFFFFFFF, lambda m: "build.txt")),
                        "build.txt declaring 4 GiB - 1"))

    def bomb_entry(name_of, total: int, honest: bool, listed_size: bool):
        def mutate(entries: list[Entry], m: dict):
            victim = name_of(m)
            stream, crc = bomb(total)
            for i, e in enumerate(entries):
                if e.name == victim:
                    entries[i] = Entry(victim, method=8, compressed=stream, crc=crc, size=total if honest else e.size)
            if listed_size:  # the manifest agrees with the bomb: only its size gives it away
                m["files"][victim]["bytes"] = total
        return mutate

    GiB3 = 3 << 30
    cs += [
        defective("zip-deflate-bomb-image", "bad-job.zip", tampered_zip(bomb_entry(first_image, GiB3, True, True)),
                  "an image entry inflating to 3 GiB of zeros, listed in the manifest with that size", timeout=60),
        defective("zip-deflate-bomb-image-lying", "bad-job.zip", tampered_zip(bomb_entry(first_image, GiB3, False, False)),
                  "an image entry declaring its old size but inflating to 3 GiB", timeout=60),
        defective("zip-deflate-bomb-manifest", "bad-job.zip",
                  tampered_zip(lambda e, m: [Entry("manifest.json", method=8, compressed=bomb(GiB3)[0], crc=bomb(GiB3)[1],
                                                   size=GiB3)] + e),
                  "manifest.json inflating to 3 GiB", ["manifest.json"], timeout=60),
        defective("zip-deflate-bomb-build-file", "bad-job.zip",
                  tampered_zip(bomb_entry(lambda m: "build.txt", GiB3, True, True)), "build.txt inflating to 3 GiB", timeout=60),
    ]

    # Entry names that climb out of the job or are absolute, listed in the manifest with correct checksums.
    def extra_entry(name: str, in_layer: bool):
        def mutate(entries: list[Entry], m: dict):
            if in_layer:  # layer 0's Vero image, byte for byte, under the new name: only the name is wrong
                victim = first_image(m)
                old = next(e for e in entries if e.name == victim)
                entries[:] = [e for e in entries if e.name != victim] + [Entry(name, compressed=old.compressed, method=old.method,
                                                                            crc=old.crc, size=old.size)]
                m["files"][name] = m["files"].pop(victim)
                m["layers"][0]["files"]["VeroWhitePlus"] = name
            else:
                data = b"notes\n"
                entries.append(Entry(name, data))
                m["files"][name] = manifest_entry(data)
        return mutate

    for tag, name in [("dotdot", "../../x"), ("absolute", "/tmp/x"), ("dotdot-inner", "previews/../../x.png"),
                      ("backslash", "..\\..\\x"), ("drive", "C:/x"), ("empty", ""), ("nul", "a\x00b")]:
        cs.append(defective(f"zip-entry-name-{tag}", "bad-job.zip", tampered_zip(extra_entry(name, False)),
                            f"an extra entry named {name!r}, listed in the manifest with its checksum", [name] if name else []))
        cs.append(defective(f"zip-layer-name-{tag}", "bad-job.zip", tampered_zip(extra_entry(name, True)),
                            f"layer 0's Vero image renamed {name!r} in the zip and the manifest", [name] if name else []))

    def dir_outside(name: str):
        def mutate(p: Path, m: dict) -> None:  # layer 0's Vero image moved out of the job, the manifest pointing at it
            victim = first_image(m)
            outside = p / name
            outside.parent.mkdir(parents=True, exist_ok=True)
            (p / victim).rename(outside)
            m["files"][name] = m["files"].pop(victim)
            m["layers"][0]["files"]["VeroWhitePlus"] = name
        return mutate

    cs.append(defective("dir-manifest-names-dotdot", "a/b/bad-job", tampered_dir(dir_outside("../../x.bmp")),
                        "a folder job's layer image at ../../x.bmp, outside the job", ["../../x.bmp"]))
    cs.append(defective("dir-manifest-names-absolute", "bad-job",
                        tampered_dir(lambda p, m: m["files"].__setitem__("/etc/hostname", manifest_entry(b""))),
                        "a folder job's manifest listing /etc/hostname"))
    cs.append(defective("dir-build-file-outside", "bad-job",
                        tampered_dir(lambda p, m: m.__setitem__("build_file", "../../../../../../../../dev/zero")),
                        "build_file pointing to ../../dev/zero", ["build_file"]))
    cs.append(defective("dir-build-file-absolute", "bad-job", tampered_dir(lambda p, m: m.__setitem__("build_file", "/dev/stdin")),
                        "build_file /dev/stdin", ["build_file"]))

    # Missing pieces.
    def drop_build(p: Path, m: dict) -> None:
        (p / "build.txt").unlink()
        m["files"].pop("build.txt", None)
    cs.append(defective("dir-no-build-file", "bad-job", tampered_dir(drop_build), "no build file (nor its manifest entry)",
                        ["build.txt"]))
    cs.append(defective("zip-no-build-file", "bad-job.zip",
                        tampered_zip(lambda e, m: (m["files"].pop("build.txt"), [x for x in e if x.name != "build.txt"])[1]),
                        "no build file in the zip", ["build.txt"]))

    def drop_material(material: str, fmt: str):
        if fmt == "dir":
            def mutate(p: Path, m: dict) -> None:
                for n in remove_material(m, material):
                    (p / n).unlink()
            return tampered_dir(mutate)

        def zmutate(entries: list[Entry], m: dict):
            gone = set(remove_material(m, material))
            return [e for e in entries if e.name not in gone]
        return tampered_zip(zmutate)

    for material in ["VeroWhitePlus", "TangoBlackPlus"]:
        for fmt, job in [("dir", "bad-job"), ("zip", "bad-job.zip")]:
            cs.append(defective(f"{fmt}-no-{material}-images", job, drop_material(material, fmt),
                                f"every {material} image removed, manifest made consistent", [material]))

    # Numbers in the manifest far out of range.
    for tag, path, value in [("width-huge", ["image", "width"], 2147483616), ("height-huge", ["image", "height"], 2147483647),
                             ("layer-count-huge", ["layer_count"], 2147483647), ("bytes-huge", None, 18446744073709551615),
                             ("first-layer-huge", ["frame", "first_layer_k"], 2147483647),
                             ("first-column-min", ["frame", "first_column_i"], -2147483648),
                             ("voxel-size-zero", ["profile", "voxel_size_mm"], [0, 0, 0]),
                             ("alignment-huge", ["profile", "column_alignment"], 2147483647),
                             ("dpi-huge", ["profile", "x_dpi"], 2147483647),
                             ("origin-inf", ["frame", "origin_mm"], [1e308, -1e308, 1e308])]:
        def mutate(p: Path, m: dict, path=path, value=value) -> None:
            if path is None:
                m["files"][first_image(m)]["bytes"] = value
            else:
                set_path(m, path, value)
        cs.append(defective(f"manifest-{tag}", "bad-job", tampered_dir(mutate), f"manifest {tag}: {value}"))
    # Zip structure.
    cs.append(defective("zip-duplicate-entry", "bad-job.zip",
                        tampered_zip(lambda e, m: e + [Entry(first_image(m), b"BM" + bytes(60))]),
                        "an image name twice in the zip, the second one different"))
    cs.append(defective("zip-encrypted-flag", "bad-job.zip",
                        tampered_zip(lambda e, m: [Entry(x.name, compressed=x.compressed, method=x.method, crc=x.crc, size=x.size,
                                                         flags=1) if x.name == first_image(m) else x for x in e]),
                        "an entry flagged encrypted"))
    cs.append(defective("zip-truncated", "bad-job.zip", _truncated_zip, "a zip cut in the middle"))
    cs.append(defective("zip-declares-65535-entries", "bad-job.zip", _zip_lying_count, "the end record declares 65,535 entries"))
    return cs


def _truncated_zip(path: Path, ctx) -> None:
    tampered_zip(lambda e, m: None)(path, ctx)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _zip_lying_count(path: Path, ctx) -> None:
    tmp = path.parent / ".fixture.zip"
    tampered_zip(lambda e, m: None)(tmp, ctx)
    from fixtures import read_zip
    raw = read_zip(tmp)
    tmp.unlink()
    write_zip(path, [Entry(n, d) for n, d in raw], declared_entries=65535)
