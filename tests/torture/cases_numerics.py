"""Class 8, numerics: scale-free inputs at extreme scales (quaternions of 1e160, normals of 1e300) must
work or be refused cleanly; coordinates of 1e300 refused; duplicate JSON keys refused in every JSON
reader; --seed -1 refused (exit 2); a section below the printer's resolution warned about; the
calibration fits must finish on 1,600 distinct fractions (generous timeout: CPU, not wall clock, is
the real measure)."""

from __future__ import annotations

import json

from engine import Case, Step
from fixtures import (BAR, Entry, bar, calibration_file, cantilever, csv_rows, design, design_dict, dither_report,
                      dma_rows, duplicate_key, profile_file, rod, tampered_dir, tampered_zip, with_mechanics)


DUPLICATE = r"duplicate|twice|more than once|repeated|again"


def slice_case(name: str, doc: str, expect: set[int], note: str, where=("d.json",), patterns=(), warnings=(),
               voxelize: bool = True) -> Case:
    steps = [Step(["slice", "d.json", "-o", "j.zip", "--quiet"], expect=expect, where=list(where), patterns=list(patterns),
                  warnings=list(warnings), outputs=["j.zip"], jobs=["j.zip"], timeout=60)]
    if voxelize:
        steps.append(Step(["voxelize", "d.json", "-o", "g.vdb"], expect=expect, where=list(where), patterns=list(patterns),
                          outputs=["g.vdb"], timeout=60))
    return Case(name, steps, files={"d.json": doc}, note=note)


def quaternion_rod(q: list, name: str = "twisted") -> dict:
    """A 4 mm rectangle rod whose frame is a constant quaternion spline (scaled as given)."""
    return rod(name, [[0, 0, 0], [4, 0, 0]], section={"shape": "rectangle", "width": 1.2, "height": 0.5},
               orientation={"degree": 1, "knots": [0, 0, 1, 1], "quaternions": [q, q]})


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    s = 0.7071067811865476
    for tag, q, exp in [("1e160", [1e160, 0, 0, 0], {0, 1}), ("1e160-all", [1e160, 1e160, 1e160, 1e160], {0, 1}),
                        ("1e-160", [1e-160, 0, 0, 1e-160], {0, 1}), ("1e300-mixed", [s * 1e300, 0, s * 1e300, 0], {0, 1}),
                        ("tiny-and-huge", [1e-300, 1e300, 0, 0], {0, 1}), ("zero", [0, 0, 0, 0], {1})]:
        cs.append(slice_case(f"quaternion-{tag}", design(quaternion_rod(q)), exp, f"orientation quaternions {q}",
                             patterns=["quaternion|orientation"]))
    cs.append(Case("quaternion-1e160-simulate",
                   [Step(["simulate", "d.json", "-o", "o.json"], expect={0, 1}, where=["d.json"], outputs=["o.json"], timeout=60)],
                   files={"d.json": json.dumps(with_mechanics(design_dict(quaternion_rod([1e160, 0, 0, 0])), "twisted"))},
                   note="quaternions of 1e160 in the solver"))
    for tag, normal, exp in [("1e300", [0, 0, 1e300], {0, 1}), ("1e300-diagonal", [0, 1e300, 1e300], {0, 1}),
                             ("1e-300", [0, 1e-300, 0], {0, 1}), ("1e-320", [0, 0, 1e-320], {0, 1}), ("zero", [0, 0, 0], {1})]:
        doc = design(rod("flat", [[0, 0, 0], [4, 0, 0]], section={"shape": "ellipse", "width": 1.2, "height": 0.5}, normal=normal))
        cs.append(slice_case(f"normal-{tag}", doc, exp, f"normal {normal}", patterns=["normal"]))
    for tag, points, exp in [("1e300", [[1e300, 0, 0], [1e300, 4, 0]], {1}), ("1e300-span", [[-1e300, 0, 0], [1e300, 0, 0]], {1}),
                             ("1e308-span", [[-1e308, 0, 0], [1e308, 0, 0]], {1}), ("1e300-z", [[0, 0, 1e300], [4, 0, 1e300]], {1}),
                             ("1e-300-rod", [[0, 0, 0], [1e-300, 0, 0]], {0, 1}), ("1e15", [[1e15, 0, 0], [1e15 + 4, 0, 0]], {0, 1})]:
        cs.append(slice_case(f"coordinates-{tag}", design(rod("far", points)), exp, f"centerline points {points}"))
    cs.append(Case("coordinates-1e300-validate", [Step(["validate", "d.json"], expect={0, 1}, where=["d.json"])],
                   files={"d.json": design(rod("far", [[1e300, 0, 0], [1e300, 4, 0]]))},
                   note="validate may accept a far rod, but must not crash"))
    cs.append(Case("coordinates-1e300-simulate",
                   [Step(["simulate", "d.json", "-o", "o.json"], expect={0, 1}, where=["d.json"], outputs=["o.json"], timeout=60)],
                   files={"d.json": json.dumps(with_mechanics(design_dict(rod("far", [[1e300, 0, 0], [1e300, 4, 0]])), "far"))},
                   note="simulate a rod at 1e300 mm"))

    # Duplicate keys: refused by every JSON reader, naming the key.
    d = design_dict(bar())
    dup_cases = [
        ("design-top-rods", ["validate", "d.json"], {"d.json": duplicate_key(d, [], "rods", [])}, "rods"),
        ("design-top-format", ["validate", "d.json"], {"d.json": duplicate_key(d, [], "format", "rodfab.design/1")}, "format"),
        ("design-diameter", ["slice", "d.json", "-o", "j.zip"],
         {"d.json": duplicate_key(d, ["rods", 0, "section"], "diameter", 2.0)}, "diameter"),
        ("design-modulus", ["voxelize", "d.json", "-o", "g.vdb"], {"d.json": duplicate_key(d, ["rods", 0], "modulus", 1)}, "modulus"),
        ("design-mechanics", ["simulate", "m.json", "-o", "o.json"],
         {"m.json": duplicate_key(cantilever(), ["mechanics"], "load_steps", 7)}, "load_steps"),
        ("profile-x-dpi", ["profiles", "./p.json"],
         {"p.json": profile_file(text=lambda p: duplicate_key(p, ["resolution"], "x_dpi", 600))}, "x_dpi"),
        ("profile-materials", ["slice", "d.json", "--profile", "./p.json", "-o", "j.zip"],
         {"d.json": BAR, "p.json": profile_file(text=lambda p: duplicate_key(p, [], "materials", []))}, "materials"),
        ("calibration-floor", ["slice", "d.json", "--calibration", "c.json", "-o", "j.zip"],
         {"d.json": BAR, "c.json": calibration_file(text=lambda c: duplicate_key(c, ["floor"], "modulus_mpa", 1.0))}, "modulus_mpa"),
        ("manifest-dir", ["inspect", "bad-job"],
         {"bad-job": tampered_dir(lambda p, m: (p / "manifest.json").write_text(duplicate_key(m, ["image"], "width", 32)),
                                  rewrite_manifest=False)}, "width"),
        ("manifest-zip", ["inspect", "bad-job.zip"],
         {"bad-job.zip": tampered_zip(lambda e, m: [Entry("manifest.json", duplicate_key(m, [], "layer_count", 1).encode())] + e)},
         "layer_count"),
    ]
    for tag, argv, files, key in dup_cases:
        where = {"design": ["d.json", "m.json"], "profile": ["p.json"], "calibration": ["c.json"],
                 "manifest": ["bad-job", "manifest"]}[tag.split("-")[0]]
        cs.append(Case(f"duplicate-key-{tag}", [Step(argv, expect={1}, where=where, patterns=[key, DUPLICATE])], files=files,
                       note=f"key {key!r} twice"))
    # The CSV header naming a column twice.
    cs.append(Case("duplicate-column-csv", [Step(["calibrate", "data.csv"], expect={1}, where=["data.csv"],
                                                 patterns=["modulus_mpa", DUPLICATE])],
                   files={"data.csv": "vero_fraction,modulus_mpa,modulus_mpa\n0,0.5,9\n0.3,8,9\n1,190,9\n"},
                   note="modulus_mpa twice in the header"))

    # Seeds: negative, too large, not integers.
    for value in ["-1", "18446744073709551616", "1.5", "1e3", "0x10", ""]:
        tag = value or "empty"
        cs += [
            Case(f"seed-{tag}-slice", [Step(["slice", "d.json", "-o", "j.zip", "--seed", value], expect={2}, where=["--seed"])],
                 files={"d.json": BAR}, note=f"--seed {value!r}"),
            Case(f"seed-{tag}-coupons", [Step(["coupons", "-o", "c.zip", "--seed", value], expect={2}, where=["--seed"])],
                 note=f"--seed {value!r}"),
            Case(f"seed-{tag}-dither-report", [Step(dither_report(**{"--seed": value}), expect={2}, where=["--seed"])],
                 note=f"--seed {value!r}"),
        ]
    cs.append(Case("seed-max-slice", [Step(["slice", "d.json", "-o", "j.zip", "--seed", "18446744073709551615", "--quiet"],
                                           outputs=["j.zip"], jobs=["j.zip"])], files={"d.json": BAR},
                   note="the largest 64-bit seed is a seed"))

    # A section below the printer's resolution: a warning naming the rod (the job is still written).
    thin = design(bar(), rod("hair", [[0, 2, 0], [4, 2, 0]], diameter=0.02, modulus=50))
    cs.append(Case("thin-rod-0.02-slice", [Step(["slice", "d.json", "-o", "j.zip"], expect={0}, outputs=["j.zip"], jobs=["j.zip"],
                                                warnings=["warning", "hair|rods\\[1\\]", "resolution|voxel|thinner"])],
                   files={"d.json": thin}, note="a 0.02 mm rod beside a 1 mm one"))
    cs.append(Case("thin-rod-0.02-voxelize", [Step(["voxelize", "d.json", "-o", "g.vdb"], expect={0}, outputs=["g.vdb"],
                                                   warnings=["warning", "hair|rods\\[1\\]"])],
                   files={"d.json": thin}, note="the same, voxelized"))
    flat = design(bar(), rod("foil", [[0, 2, 0], [4, 2, 0]], section={"shape": "rectangle", "width": 1.0, "height": 0.01},
                             normal=[0, 0, 1], modulus=50))
    cs.append(Case("thin-rectangle-0.01-slice", [Step(["slice", "d.json", "-o", "j.zip"], expect={0}, outputs=["j.zip"],
                                                      jobs=["j.zip"], warnings=["warning", "foil|rods\\[1\\]"])],
                   files={"d.json": flat}, note="a 1 x 0.01 mm rectangle: thinner than a layer"))

    # Calibration fits on many distinct fractions: they must finish (20 s is generous; CPU is ~ms).
    data = {"data.csv": csv_rows(dma_rows(1600, spread=0.03))}
    mono = {"data.csv": csv_rows(dma_rows(1600))}
    for model, files in [("lichtenecker", data), ("log-power", data), ("pchip", mono)]:
        cs.append(Case(f"calibrate-{model}-1600", [Step(["calibrate", "data.csv", "--model", model, "-o", "cal.json"],
                                                        outputs=["cal.json"], timeout=20)], files=files,
                       note=f"--model {model} on 1,600 distinct fractions"))
    cs.append(Case("calibrate-lichtenecker-1600-plot", [Step(["calibrate", "data.csv", "--model", "lichtenecker", "--plot", "fit.png"],
                                                             outputs=["fit.png"], timeout=20)], files=data,
                   note="and its plot"))
    big = {"data.csv": csv_rows(dma_rows(20000, spread=0.03))}
    cs.append(Case("calibrate-lichtenecker-20000", [Step(["calibrate", "data.csv", "--model", "lichtenecker"], expect={0, 1},
                                                         where=["data.csv"], timeout=20)], files=big,
                   note="20,000 distinct fractions: fit, or refuse with a reason"))
    return cs
