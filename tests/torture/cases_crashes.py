"""Class 3, crashes: numbers beyond float's range, JSON nested ~60,000 levels deep in every reader
(design, profile, calibration, calibrate's CSV, blue-noise mask, job manifest), and options far out
of range. Every one must end with exit 1 (bad file) or 2 (bad option) and a located message, or
succeed with valid output where the input is odd but legal; never a signal, a hang or a runaway."""

from __future__ import annotations

import copy
import json
import struct
from pathlib import Path

from engine import Case, Step
from fixtures import (BAR, DEEP, Entry, bar, calibration_file, cantilever, csv_rows, deep_array, deep_object, design,
                      design_dict, dither_report, dma_rows, fifo, profile_file, raw_number, tampered_dir, tampered_zip,
                      with_deep, with_mechanics)


def bad_file(name: str, argv: list[str], files: dict, where: list[str], patterns: list[str] = (), expect=frozenset({1}),
             outputs: list[str] = (), jobs: list[str] = (), note: str = "", timeout: float = 30) -> Case:
    return Case(name, [Step(argv, expect=set(expect), where=where, patterns=list(patterns), outputs=list(outputs),
                            jobs=list(jobs), timeout=timeout)], files=files, note=note)


def bad_option(name: str, argv: list[str], option: str, files: dict | None = None, expect=frozenset({2}),
               outputs: list[str] = (), jobs: list[str] = (), note: str = "") -> Case:
    return Case(name, [Step(argv, expect=set(expect), where=[option], outputs=list(outputs), jobs=list(jobs))],
                files=files or {}, note=note or f"{option} out of range")


def mask_bytes(size=(2, 2, 2), voxel_nm=(42300, 84600, 30000), sigma_nm=100000, density_ppm=100000,
               payload: bytes | None = None) -> bytes:
    """A blue-noise mask file in the format of materials/blue_noise_mask.cpp (little-endian)."""
    cells = size[0] * size[1] * size[2]
    bits = max(1, (cells - 1).bit_length())
    head = b"RFBNMASK" + struct.pack("<I", 1) + struct.pack("<3I", *size) + struct.pack("<3I", *voxel_nm)
    head += struct.pack("<II", sigma_nm, density_ppm) + struct.pack("<Q", 7) + struct.pack("<I", bits)
    if payload is None:
        packed, bit = bytearray((cells * bits + 7) // 8), 0
        for r in range(cells):  # ranks 0 .. cells-1 in order: a valid permutation
            for b in range(bits):
                if (r >> b) & 1:
                    packed[bit // 8] |= 1 << (bit % 8)
                bit += 1
        payload = bytes(packed)
    return head + payload


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    d = design_dict(bar())
    mech = with_mechanics(d, "bar")

    # Moduli beyond float (the grid stores float): refuse, or clamp to the stiffest mix and print.
    for tag, value in [("4e38", 4e38), ("3.4e38", 3.4e38), ("1e-320", 1e-320)]:
        for where_in, doc in [("const", design(bar(modulus=value))),
                              ("spline", design(bar(modulus={"degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [8, value, 40]})))]:
            cs.append(bad_file(f"modulus-{tag}-{where_in}-slice", ["slice", "d.json", "-o", "j.zip", "--quiet"], {"d.json": doc},
                               ["d.json"], ["modulus"], expect={0, 1}, outputs=["j.zip"], jobs=["j.zip"],
                               note=f"E = {tag} MPa"))
        cs.append(bad_file(f"modulus-{tag}-voxelize", ["voxelize", "d.json", "-o", "g.vdb"],
                           {"d.json": design(bar(modulus=value))}, ["d.json"], ["modulus"], expect={0, 1},
                           outputs=["g.vdb"], note=f"E = {tag} MPa into a float grid"))
        cs.append(bad_file(f"modulus-{tag}-simulate", ["simulate", "d.json", "-o", "o.json"],
                           {"d.json": json.dumps(with_mechanics(design_dict(bar(modulus=value)), "bar"))}, ["d.json"],
                           expect={0, 1}, outputs=["o.json"], note=f"E = {tag} MPa in the solver (a located refusal, "
                                                                     "for any reason, is fine)"))
    spline = design_dict(bar(modulus={"degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [8, 100, 40]}))
    for tag, literal in [("inf", "1e309"), ("minus-inf", "-1e400")]:
        doc = raw_number(spline, ["rods", 0, "modulus", "values", 1], literal)
        for cmd, argv, outs in [("validate", ["validate", "d.json"], []), ("slice", ["slice", "d.json", "-o", "j.zip"], ["j.zip"]),
                                ("voxelize", ["voxelize", "d.json", "-o", "g.vdb"], ["g.vdb"])]:
            cs.append(bad_file(f"modulus-{tag}-mixed-{cmd}", argv, {"d.json": doc}, ["d.json"], ["modulus"],
                               note=f"E(s) values [8, {literal}, 40]"))
        cs.append(bad_file(f"modulus-{tag}-mixed-simulate", ["simulate", "d.json", "-o", "o.json"],
                           {"d.json": raw_number(with_mechanics(spline, "bar"), ["rods", 0, "modulus", "values", 1], literal)},
                           ["d.json"], ["modulus"], note=f"E(s) values [8, {literal}, 40]"))
    for field, key, path in [("point", "points", ["rods", 0, "centerline", "points", 1, 0]),
                             ("weight", "weights", ["rods", 0, "centerline", "weights", 1]),
                             ("knot", "knots", ["rods", 0, "centerline", "knots", 3]),
                             ("diameter", "diameter", ["rods", 0, "section", "diameter"])]:
        doc = design_dict(bar(weights=[1, 1]) if field == "weight" else bar())
        cs.append(bad_file(f"design-{field}-inf-slice", ["slice", "d.json", "-o", "j.zip"], {"d.json": raw_number(doc, path, "1e309")},
                           ["d.json"], [key], note=f"a {field} of 1e309"))
    cs.append(bad_file("design-degree-int-max", ["slice", "d.json", "-o", "j.zip"],
                       {"d.json": design(bar(degree=2147483647, knots=[0, 0, 1, 1]))}, ["d.json"], ["degree"], note="degree 2^31 - 1"))
    cs.append(bad_file("design-degree-huge-validate", ["validate", "d.json"],
                       {"d.json": raw_number(d, ["rods", 0, "centerline", "degree"], "1e20")}, ["d.json"], ["degree"],
                       note="degree 1e20"))
    cs.append(bad_file("mechanics-force-inf", ["simulate", "d.json", "-o", "o.json"],
                       {"d.json": raw_number(mech, ["mechanics", "loads", 0, "force", 2], "1e309")}, ["d.json"], ["force"],
                       note="a load of 1e309 N"))
    cs.append(bad_file("mechanics-load-steps-huge", ["simulate", "d.json", "-o", "o.json"],
                       {"d.json": raw_number(mech, ["mechanics", "load_steps"], "4294967297")}, ["d.json"], ["load_steps"],
                       note="load_steps 2^32 + 1"))
    # Places inside a rod ({"rod", "parameter"}, or a point found on a rod): out of range, far away,
    # more than one rod holds.
    inner = copy.deepcopy(mech)
    inner["mechanics"]["loads"][0]["at"] = {"rod": "bar", "parameter": 0.0}
    cs.append(bad_file("mechanics-parameter-inf", ["simulate", "d.json", "-o", "o.json"],
                       {"d.json": raw_number(inner, ["mechanics", "loads", 0, "at", "parameter"], "1e309")}, ["d.json"],
                       ["parameter"], note="a load at parameter 1e309"))
    for tag, u in [("huge", 1e300), ("negative", -1e-300), ("past-end", 1.0000001)]:
        far = copy.deepcopy(inner)
        far["mechanics"]["loads"][0]["at"]["parameter"] = u
        cs.append(bad_file(f"mechanics-parameter-{tag}", ["simulate", "d.json", "-o", "o.json"], {"d.json": json.dumps(far)},
                           ["d.json", "mechanics.loads[0].at.parameter"], ["outside rod"], note=f"a load at parameter {u}"))
    many = copy.deepcopy(inner)
    many["mechanics"]["joint_tolerance"] = 1e-6  # 5000 places 0.8 um apart stay apart
    many["mechanics"]["loads"] = [{"at": {"rod": "bar", "parameter": (i + 1) / 5001}, "force": [0, 0, -1e-6]} for i in range(5000)]
    cs.append(bad_file("mechanics-parameter-5000-places", ["simulate", "d.json", "-o", "o.json"], {"d.json": json.dumps(many)},
                       ["d.json", "rods[0]"], ["interior places"], note="5000 loads inside one rod"))
    point = copy.deepcopy(mech)
    point["mechanics"]["loads"][0]["at"] = {"point": [1e300, -1e300, 1e300]}
    cs.append(bad_file("mechanics-point-1e300", ["simulate", "d.json", "-o", "o.json"], {"d.json": json.dumps(point)},
                       ["d.json", "mechanics.loads[0].at.point"], ["no rod lies within"], note="a load at a point 1e300 away"))

    # JSON nested 60,000 levels deep, in every reader.
    deep_a, deep_o = deep_array(), deep_object()
    for cmd, argv in [("validate", ["validate", "d.json"]), ("slice", ["slice", "d.json", "-o", "j.zip"]),
                      ("voxelize", ["voxelize", "d.json", "-o", "g.vdb"]), ("simulate", ["simulate", "d.json", "-o", "o.json"])]:
        cs.append(bad_file(f"deep-design-array-{cmd}", argv, {"d.json": deep_a}, ["d.json"], note=f"[[[...]]] {DEEP} deep"))
        cs.append(bad_file(f"deep-design-object-{cmd}", argv, {"d.json": deep_o}, ["d.json"], note=f'{{"a":{{"a":...}}}} {DEEP} deep'))
    cs += [
        bad_file("deep-design-points", ["slice", "d.json", "-o", "j.zip"],
                 {"d.json": with_deep(d, ["rods", 0, "centerline", "points"])}, ["d.json"], ["points"],
                 note="rods[0].centerline.points nested"),
        bad_file("deep-design-description", ["validate", "d.json"], {"d.json": with_deep({**d, "description": ""}, ["description"])},
                 ["d.json"], ["description"], note="description nested instead of a string"),
        bad_file("deep-design-metadata-slice", ["slice", "d.json", "-o", "j.zip", "--quiet"],
                 {"d.json": with_deep({**d, "metadata": {}}, ["metadata"], deep_o)}, ["d.json"], ["metadata"], expect={0, 1},
                 outputs=["j.zip"], jobs=["j.zip"], note="metadata (anything) nested: refuse, or carry it into a job inspect reads"),
        bad_file("deep-design-mechanics", ["simulate", "d.json", "-o", "o.json"], {"d.json": with_deep(mech, ["mechanics", "loads"])},
                 ["d.json"], ["loads"], note="mechanics.loads nested"),
        bad_file("deep-profile-file-profiles", ["profiles", "./p.json"], {"p.json": deep_a}, ["p.json"], note="a profile file nested"),
        bad_file("deep-profile-file-slice", ["slice", "d.json", "--profile", "./p.json", "-o", "j.zip"],
                 {"d.json": BAR, "p.json": deep_o}, ["p.json"], note="--profile FILE nested"),
        bad_file("deep-profile-field", ["slice", "d.json", "--profile", "./p.json", "-o", "j.zip", "--quiet"],
                 {"d.json": BAR, "p.json": profile_file(text=lambda p: with_deep(p, ["materials", 0, "preview_rgb"]))},
                 ["p.json"], ["preview_rgb"], note="materials[0].preview_rgb nested"),
        bad_file("deep-profile-note", ["profiles", "./p.json"],
                 {"p.json": profile_file(text=lambda p: with_deep(p, ["resolution", "note"], deep_o))}, ["p.json"], expect={0, 1},
                 note="a free-text note nested"),
        bad_file("deep-calibration-file", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip"],
                 {"d.json": BAR, "c.json": deep_a}, ["c.json"], note="--calibration FILE nested"),
        bad_file("deep-calibration-points", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip"],
                 {"d.json": BAR, "c.json": calibration_file(text=lambda c: with_deep(c, ["parameters", "points"]))},
                 ["c.json"], ["points"], note="parameters.points nested"),
        bad_file("deep-calibration-data", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip", "--quiet"],
                 {"d.json": BAR, "c.json": calibration_file(text=lambda c: with_deep(c, ["data", "measurements"], deep_o))},
                 ["c.json"], expect={0, 1}, outputs=["j.zip"], jobs=["j.zip"], note="data.measurements nested"),
        bad_file("deep-csv-line", ["calibrate", "data.csv"], {"data.csv": deep_a + "\n" + csv_rows(dma_rows(3))},
                 ["data.csv"], note="a CSV whose header is 120,000 brackets"),
        bad_file("deep-csv-notes", ["calibrate", "data.csv"],
                 {"data.csv": "vero_fraction,modulus_mpa,notes\n0,0.5,\"" + deep_a + "\"\n0.3,8,x\n1,190,\""
                              + deep_o.replace('"', '""') + "\"\n"},
                 ["data.csv"], expect={0, 1}, note="quoted notes fields 120,000 characters of nesting"),
        bad_file("deep-csv-quotes", ["calibrate", "data.csv"],
                 {"data.csv": "vero_fraction,modulus_mpa\n" + '"' * 120001 + "\n0,0.5\n1,190\n"}, ["data.csv"],
                 note="120,001 double quotes"),
        bad_file("deep-manifest-dir", ["inspect", "deep-job"],
                 {"deep-job": tampered_dir(lambda p, m: (p / "manifest.json").write_text(deep_a), rewrite_manifest=False)},
                 ["manifest.json", "deep-job"], note="a folder job's manifest.json nested"),
        bad_file("deep-manifest-zip", ["inspect", "deep-job.zip"],
                 {"deep-job.zip": tampered_zip(lambda e, m: [Entry("manifest.json", deep_o.encode())] + e)},
                 ["manifest.json", "deep-job.zip"], note="a zip job's manifest.json nested"),
        bad_file("deep-manifest-layers", ["inspect", "deep-job"],
                 {"deep-job": tampered_dir(lambda p, m: m.__setitem__("layers", [json.loads("[" * 500 + "]" * 500)]))},
                 ["manifest.json", "deep-job", "layers"], note="layers nested 500 deep"),
        bad_file("deep-manifest-metadata", ["inspect", "deep-job"],
                 {"deep-job": _deep_metadata_job()},
                 ["manifest.json", "deep-job"], expect={0, 1}, note="metadata nested 60,000 deep (free-form, checksums intact)"),
    ]

    # Options far out of range: exit 2 naming the option (or 1 for a budget refusal where noted).
    b = {"d.json": BAR}
    m = {"m.json": json.dumps(cantilever())}
    for value in ["100000", "-1", "2147483648", "1e3"]:
        cs += [
            bad_option(f"slice-threads-{value}", ["slice", "d.json", "-o", "j.zip", "--threads", value], "--threads", b),
            bad_option(f"voxelize-threads-{value}", ["voxelize", "d.json", "-o", "g.vdb", "--threads", value], "--threads", b),
            bad_option(f"coupons-threads-{value}", ["coupons", "-o", "c.zip", "--threads", value], "--threads"),
            bad_option(f"simulate-threads-{value}", ["simulate", "m.json", "-o", "o.json", "--threads", value], "--threads", m),
        ]
    # Boost's error text loops forever on a token holding one of its own placeholders (found by fuzz_command_line).
    for placeholder in ["%canonical_option%", "%option%", "%value%", "%original_token%", "%prefix%"]:
        bare = placeholder.strip("%")
        cs += [
            bad_option(f"simulate-option-named-{bare}", ["simulate", "m.json", "-o", "o.json", f"-{placeholder}o"], bare, m,
                       note="an option name holding a Boost placeholder"),
            bad_option(f"slice-threads-{bare}", ["slice", "d.json", "-o", "j.zip", "--threads", placeholder], bare, b,
                       note="an option value holding a Boost placeholder"),
            bad_option(f"coupons-missing-value-{bare}", ["coupons", f"--{placeholder}"], bare,
                       note="a long option holding a Boost placeholder"),
        ]
    for block, exp in [("2000x2000x2000", {1, 2}), ("100000x100000x1", {1, 2}), ("1x1x4294967297", {2}), ("0x64x180", {2}),
                       ("-5x64x180", {2}), ("128x64", {2})]:
        cs.append(bad_option(f"dither-report-block-{block}", dither_report(**{"--block": block}), "--block", expect=exp,
                             note="a budget refusal (1) or a range check (2), naming --block"))
    for opt, value in [("--rod-diameter", "1e300"), ("--rod-diameter", "nan"), ("--rod-diameter", "-1"), ("--rod-diameter", "0"),
                       ("--rod-length", "1e300"), ("--rod-length", "inf"), ("--rod-fraction", "nan"), ("--rod-fraction", "1.5"),
                       ("--fractions", "0.1,1e309"), ("--fractions", "nan"), ("--fractions", ""), ("--rod-axis", "w")]:
        cs.append(bad_option(f"dither-report{opt}-{value or 'empty'}", dither_report(**{opt: value}), opt,
                             expect={1, 2} if value == "1e300" else {2}))
    for value in ["2147483647", "2147483648", "-1", "99999999999999999999"]:
        ok = value == "2147483647"
        cs.append(bad_option(f"slice-band-layers-{value}", ["slice", "d.json", "-o", "j.zip", "--quiet", "--band-layers", value],
                             "--band-layers", b, expect={0, 2} if ok else {2}, outputs=["j.zip"], jobs=["j.zip"],
                             note="a band of all layers is fine; overflow is not"))
        cs.append(bad_option(f"coupons-band-layers-{value}", ["coupons", "-o", "c.zip", "--quiet", "--fractions", "0,1",
                                                              "--size", "3x2x0.3", "--band-layers", value],
                             "--band-layers", {}, expect={0, 2} if ok else {2}, outputs=["c.zip"], jobs=["c.zip"]))
    for size in ["1e-6,1e-6,1e-6", "1e-320,0.1,0.1", "inf,0.1,0.1", "nan,0.1,0.1", "0.0001,0.0001,0.0001"]:
        c = bad_option(f"voxelize-voxel-size-{size}", ["voxelize", "d.json", "-o", "g.vdb", "--voxel-size", size],
                       "--voxel-size", b, expect={1, 2}, note="voxels so small the grid cannot be held (or not a number)")
        c.steps[0].where.append("voxel size")
        cs.append(c)
    cs.append(bad_option("voxelize-voxel-size-1e300", ["voxelize", "d.json", "-o", "g.vdb", "--voxel-size", "1e300,1e300,1e300"],
                         "--voxel-size", b, expect={0, 1, 2}, outputs=["g.vdb"], note="one voxel bigger than the universe"))
    for opt, value, exp in [("--size", "1e300x5x1.5", {1, 2}), ("--size", "30x5x1e-300", {1, 2}), ("--size", "30x5xnan", {2}),
                            ("--gap", "1e300", {1, 2}), ("--gap", "-1", {2}), ("--gap", "nan", {2}),
                            ("--fractions", "0,1e-9,...,1", {1, 2}), ("--fractions", "0,0.5,nan", {2}), ("--fractions", "1e309", {2}),
                            ("--fractions", "0," * 30000 + "1", {1, 2})]:
        c = bad_option(f"coupons{opt}-{value[:24].rstrip(',')}", ["coupons", "-o", "c.zip", opt, value], opt, expect=exp)
        if opt == "--size":  # "a bar of ... mm does not fit the tray" names the size the option gave
            c.steps[0].where.append("bar of")
        cs.append(c)
    for opt, value in [("--degree", "1000000"), ("--degree", "-4"), ("--load-steps", "2147483647"), ("--load-steps", "-1"),
                       ("--tolerance", "nan"), ("--tolerance", "-1"), ("--max-iterations", "-1"),
                       ("--max-iterations", "2147483648"), ("--spans", "-1")]:
        cs.append(bad_option(f"simulate{opt}-{value}", ["simulate", "m.json", "-o", "o.json", opt, value], opt, m,
                             expect={1, 2} if value == "2147483647" else {2}))
    for value in ["1e309", "nan", "inf", "-inf"]:
        cs.append(bad_option(f"calibrate-floor-{value}", ["calibrate", "data.csv", "--floor-mpa", value], "--floor-mpa",
                             {"data.csv": csv_rows(dma_rows(5))}))

    # Numbers read from calibration files and CSV data.
    def cal(edit):
        return {"d.json": BAR, "c.json": calibration_file(edit)}
    for tag, edit, path_word in [
        ("point-modulus-4e38", lambda c: c["parameters"]["points"][2].__setitem__("modulus_mpa", 4e38), "modulus"),
        ("point-fraction-2", lambda c: c["parameters"]["points"][2].__setitem__("vero_fraction", 2.0), "vero_fraction"),
        ("floor-negative", lambda c: c["floor"].__setitem__("modulus_mpa", -8.0), "floor"),
        ("max-modulus-zero", lambda c: c.__setitem__("max_modulus_mpa", 0.0), "max_modulus"),
        ("no-points", lambda c: c["parameters"].__setitem__("points", []), "points"),
        ("points-not-increasing", lambda c: c["parameters"]["points"].reverse(), "points"),
    ]:
        cs.append(bad_file(f"calibration-{tag}", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip"], cal(edit),
                           ["c.json"], [path_word], note=f"calibration file: {tag}"))
    cs.append(bad_file("calibration-modulus-inf", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip"],
                       {"d.json": BAR, "c.json": calibration_file(
                           text=lambda c: raw_number(c, ["parameters", "points", 1, "modulus_mpa"], "1e309"))},
                       ["c.json"], ["modulus"], note="a point's modulus 1e309"))
    cs.append(bad_file("calibration-many-points", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip", "--quiet"],
                       {"d.json": BAR, "c.json": calibration_file(lambda c: c["parameters"].__setitem__(
                           "points", [{"vero_fraction": i / 199999, "modulus_mpa": 0.5 * 380 ** (i / 199999)}
                                      for i in range(200000)]))},
                       ["c.json"], expect={0, 1}, outputs=["j.zip"], jobs=["j.zip"], note="200,000 points"))
    for tag, text in [
        ("modulus-inf", csv_rows([(0, 0.5), (0.3, "1e309"), (1, 190)])),
        ("fraction-denormal", csv_rows([(0, 0.5), ("1e-320", 0.6), (0.3, 8), (1, 190)])),
        ("temperature-inf", "vero_fraction,modulus_mpa,temperature_c\n0,0.5,60\n0.3,8,1e309\n1,190,60\n"),
        ("nul-bytes", "vero_fraction,modulus_mpa\n0,0.5\n0.3,8\x00\x00\n1,190\n"),
        ("huge-header", "vero_fraction,modulus_mpa," + ",".join(f"c{i}" for i in range(200000)) + "\n0,0.5\n0.3,8\n1,190\n"),
        ("long-line", csv_rows([(0, 0.5), (0.3, 8), (1, "190" + "0" * 5000000)])),
        ("million-rows", csv_rows([(f"{(i % 1000) / 999:.4f}", f"{0.5 * 380 ** ((i % 1000) / 999):.5g}") for i in range(300000)])),
    ]:
        ok = tag in ("fraction-denormal", "million-rows")
        cs.append(bad_file(f"csv-{tag}", ["calibrate", "data.csv", "-o", "cal.json"], {"data.csv": text}, ["data.csv"],
                           expect={0, 1} if ok or tag == "temperature-inf" else {1}, outputs=["cal.json"],
                           note=f"calibration data: {tag}", timeout=60))

    # The blue-noise mask reader (dither-report --mask).
    for tag, files, arg, exp in [
        ("dev-zero", {}, "/dev/zero", {1}),
        ("fifo", {"mask.rfbn": fifo}, "mask.rfbn", {1}),
        ("directory", {"mask.rfbn/x": ""}, "mask.rfbn", {1}),
        ("voxel-size-zero", {"mask.rfbn": mask_bytes(voxel_nm=(0, 0, 0))}, "mask.rfbn", {1}),
        ("sigma-zero", {"mask.rfbn": mask_bytes(sigma_nm=0)}, "mask.rfbn", {1}),
        ("huge-declared", {"mask.rfbn": mask_bytes(size=(1024, 1024, 1024), payload=b"\0" * 64)}, "mask.rfbn", {1}),
        ("valid-tiny", {"mask.rfbn": mask_bytes()}, "mask.rfbn", {0, 1}),
    ]:
        cs.append(bad_file(f"mask-{tag}", dither_report(**{"--dither": "blue", "--mask": arg}), files, [arg, "--mask"],
                           expect=exp, note=f"--mask {tag}"))
    return cs


def _deep_metadata_job():
    def mutate(path: Path, manifest: dict) -> None:
        text = json.dumps({**manifest, "metadata": "\u2063M\u2063"}, indent=1)
        (path / "manifest.json").write_text(text.replace(json.dumps("\u2063M\u2063"), deep_object()))
    return tampered_dir(mutate, rewrite_manifest=False)
