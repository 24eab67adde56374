"""Class 7, printer profiles: names that become file names (the build file, the materials, the profile
itself) and numbers that size the images must be refused when the profile is loaded, with the file
and the JSON path named: by `rodfab profiles FILE` and by `rodfab slice --profile FILE` (which must
then write nothing)."""

from __future__ import annotations

from engine import Case, Step
from fixtures import BAR, profile_file


def edit(path: list, value):
    def apply(p: dict) -> None:
        node = p
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
    return apply


def refused(tag: str, change, field: str, note: str) -> list[Case]:
    files = {"p.json": profile_file(change), "d.json": BAR}
    return [
        Case(f"{tag}-profiles", [Step(["profiles", "./p.json"], expect={1}, where=["p.json"], patterns=[field])], files=files,
             note=note),
        Case(f"{tag}-slice", [Step(["slice", "d.json", "--profile", "./p.json", "-o", "j.zip"], expect={1}, where=["p.json"],
                                   patterns=[field])], files=files, note=note + " (slice writes nothing)"),
    ]


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    build = ["build_file", "name"]
    for tag, name in [("backslash", "a\\build.txt"), ("drive", "C:build.txt"), ("drive-backslash", "C:\\build.txt"),
                      ("dotdot", ".."), ("dot", "."), ("empty", ""), ("nul", "build\u0000.txt"), ("newline", "build\n.txt"),
                      ("manifest", "manifest.json"), ("previews", "previews"), ("too-long", "b" * 5000 + ".txt"),
                      ("trailing-slash", "build.txt/"), ("image-name", "VeroWhitePlus_0000.bmp")]:
        cs += refused(f"build-file-{tag}", edit(build, name), "build_file", f"build file name {name[:40]!r}")
    mat = ["materials", 1, "name"]
    for tag, name in [("case-duplicate", "VEROWHITEPLUS"), ("case-duplicate-mixed", "verowhitePlus"), ("empty", ""),
                      ("dotdot", ".."), ("dot", "."), ("nul", "Tango\u0000"), ("too-long", "T" * 5000),
                      ("newline", "Tango\nBlack"), ("control", "Tango\u0007")]:
        cs += refused(f"material-name-{tag}", edit(mat, name), "materials", f"material name {name[:40]!r}")

    def vero_and_VERO(p: dict) -> None:
        p["materials"][0]["name"] = "Vero"
        p["materials"][1]["name"] = "VERO"
    cs += refused("material-names-Vero-VERO", vero_and_VERO, "materials", "materials Vero and VERO (one file on a "
                                                                                  "case-insensitive file system)")
    for tag, name in [("slash", "../../dev/zero"), ("absolute", "/dev/zero"), ("backslash", "a\\b"), ("empty", "")]:
        cs += refused(f"profile-name-{tag}", edit(["name"], name), "name", f"profile name {name!r} (inspect looks it up)")
    for tag, value in [("100000-columns", [100000, 16]), ("100000-rows", [32, 100000]), ("both-50000", [50000, 50000])]:
        cs += refused(f"padding-{tag}", edit(["image", "padding_voxels"], value), "padding_voxels", f"padding_voxels {value}")
    for tag, path, value, field in [
        ("tray-1e300", ["tray_mm"], [1e300, 1e300, 1e300], "tray_mm"),
        ("tray-1e9", ["tray_mm"], [1e9, 390, 200], "tray_mm"),
        ("density-1e300", ["materials", 0, "density_g_per_ml"], 1e300, "density"),
        ("layer-1e-9", ["resolution"], {"x_dpi": 600, "y_dpi": 300, "layer_thickness_mm": 1e-9,
                                        "voxel_size_mm": [0.0423, 0.0846, 1e-9]}, "layer_thickness_mm"),
        ("layer-1e300", ["resolution"], {"x_dpi": 600, "y_dpi": 300, "layer_thickness_mm": 1e300,
                                         "voxel_size_mm": [0.0423, 0.0846, 1e300]}, "layer_thickness_mm"),
        ("format-version-huge", ["build_file", "format_version"], 1e300, "format_version"),
        ("slots-huge", ["model_material_slots"], 4294967296, "model_material_slots"),
        ("layer-digits-huge", ["image", "layer_digits"], 4294967297, "layer_digits"),
    ]:
        cs += refused(f"number-{tag}", edit(path, value), field, f"{'.'.join(map(str, path))} = {str(value)[:60]}")
    return cs
