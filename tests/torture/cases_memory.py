"""Class 2, ordinary designs that exhaust memory: small, valid designs (they pass validate) on which the
rasterizer or the solver ran away (22 GB for the README's rod at 4 mm diameter), and one genuinely big
part. Every run is under the address-space cap; the --max-memory runs must also stay within the budget
they were given (peak resident memory). An honest refusal is exit 1 with a located message; success is
fine too (the job must then pass inspect). SIGTERM after 2 s must end a run within 1 s, exit 143,
nothing left behind."""

from __future__ import annotations

import json
import math
import signal

from engine import Case, Step
from fixtures import README_CENTERLINE, cantilever, design_dict, readme_rod, rod, with_mechanics

OK_OR_REFUSED = {0, 1}


def helix(radius: float, pitch: float, turns: int, per_turn: int = 8) -> list:
    n = turns * per_turn + 1
    return [[radius * math.cos(2 * math.pi * i / per_turn), radius * math.sin(2 * math.pi * i / per_turn),
             pitch * i / per_turn] for i in range(n)]


def runaway_designs() -> dict[str, tuple[dict, str]]:
    """name -> (design, what it is). Each carries a mechanics block (clamped start, end force)."""
    c = README_CENTERLINE
    d: dict[str, tuple[dict, str]] = {}

    def add(name: str, r: dict, note: str) -> None:
        d[name] = (with_mechanics(design_dict(r), r["name"]), note)

    add("readme-d4", readme_rod(section={"shape": "circle", "diameter": 4}), "the README's rod at 4 mm diameter")
    add("readme-d6", readme_rod(section={"shape": "circle", "diameter": 6}), "the README's rod at 6 mm diameter")
    add("weights-1e3", readme_rod(centerline={**c, "weights": [1, 1e3, 1e3, 1]}), "rational weights [1, 1e3, 1e3, 1]")
    add("weights-1e-3", readme_rod(centerline={**c, "weights": [1, 1e-3, 1e-3, 1]}), "rational weights [1, 1e-3, 1e-3, 1]")
    add("cusp", rod("cusp", [[0, 0, 0], [3, 3, 0], [0, 3, 0], [3, 0, 0]], degree=3, diameter=1.0),
        "a cubic with a cusp (zero tangent at t = 0.5)")
    add("cusp-xz", rod("cusp", [[0, 0, 0], [3, 0, 3], [0, 0, 3], [3, 0, 0]], degree=3, diameter=0.8),
        "the cusp standing up in x-z")
    add("ellipse-5x0.01", readme_rod(section={"shape": "ellipse", "width": 5, "height": 0.01}),
        "a 5 x 0.01 mm ellipse on the README's rod")
    add("rectangle-8x0.004", readme_rod(section={"shape": "rectangle", "width": 8, "height": 0.004}),
        "an 8 x 0.004 mm rectangle")
    add("far-1e10", readme_rod(centerline={**c, "points": [[p[0] + 1e10, p[1], p[2]] for p in c["points"]]}),
        "the README's rod 1e10 mm away along x")
    add("far-1e7-yz", readme_rod(centerline={**c, "points": [[p[0], p[1] - 1e7, p[2] + 5e6] for p in c["points"]]}),
        "the README's rod 1e7 mm away along y and z")
    add("tight-helix", rod("coil", helix(0.3, 0.6, 4), degree=3, diameter=1.0),
        "a coil of radius 0.3 mm with a 1 mm wire: the tube overlaps itself")
    add("near-double-knot", rod("knotty", [[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 1], [4, 0, 1], [5, 0, 0]], degree=3,
                                knots=[0, 0, 0, 0, 0.5, 0.5 + 1e-12, 1, 1, 1, 1], diameter=1.5),
        "interior knots 1e-12 apart")
    add("normal-near-tangent", rod("flat", [[0, 0, 0], [5, 0, 0]], section={"shape": "ellipse", "width": 2, "height": 0.5},
                                   normal=[1, 1e-4, 0]),
        "an ellipse whose reference normal is almost the tangent")
    add("zigzag-degree5", rod("zigzag", [[i * 0.3, (i % 2) * 1.5, 0] for i in range(12)], degree=5, diameter=2.5),
        "a degree-5 zigzag thicker than its bends")
    return d


def big_solid() -> dict:
    """A 450 x 150 x 150 mm solid rod: 7e10 voxels at printer resolution, a legitimate part that takes
    long to slice and cannot be voxelized into memory."""
    return with_mechanics(design_dict(rod("trunk", [[0, 0, 0], [300, 0, 0]], diameter=150.0, modulus=60)), "trunk")


def located(*names: str) -> list[str]:
    return [*names, "--max-memory"]


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    term = (signal.SIGTERM, 2.0)
    for name, (d, note) in runaway_designs().items():
        files = {"d.json": json.dumps(d, indent=1)}
        cs += [
            Case(f"{name}-slice", [Step(["slice", "d.json", "-o", "j.zip", "--quiet"], expect=OK_OR_REFUSED, max_memory=True,
                                        where=located("d.json"), outputs=["j.zip"], jobs=["j.zip"], timeout=60)],
                 files=files, note=note),
            Case(f"{name}-voxelize", [Step(["voxelize", "d.json", "-o", "g.vdb"], expect=OK_OR_REFUSED, max_memory=True,
                                           where=located("d.json"), outputs=["g.vdb"], timeout=60)],
                 files=files, note=note),
            Case(f"{name}-simulate", [Step(["simulate", "d.json", "-o", "out.json"], expect=OK_OR_REFUSED, max_memory=True,
                                           where=located("d.json"), outputs=["out.json"], timeout=60)],
                 files=files, note=note),
            Case(f"{name}-slice-sigterm", [Step(["slice", "d.json", "-o", "j.zip", "--quiet"], expect=OK_OR_REFUSED,
                                                where=["d.json"], outputs=["j.zip"], jobs=["j.zip"], signal=term,
                                                timeout=60)],
                 files=files, note=note + "; SIGTERM after 2 s, default budget"),
        ]
    # The default budget (from the machine's memory) under the address-space cap: a clean refusal or a
    # success, never bad_alloc or a crash.
    for name in ["readme-d4", "weights-1e3", "cusp", "ellipse-5x0.01", "far-1e10", "tight-helix"]:
        d, note = runaway_designs()[name]
        files = {"d.json": json.dumps(d, indent=1)}
        cs += [
            Case(f"{name}-slice-default-budget",
                 [Step(["slice", "d.json", "-o", "j.zip", "--quiet"], expect=OK_OR_REFUSED, where=["d.json", "--max-memory"],
                       outputs=["j.zip"], jobs=["j.zip"], timeout=60)], files=files, note=note),
            Case(f"{name}-voxelize-sigterm",
                 [Step(["voxelize", "d.json", "-o", "g.vdb"], expect=OK_OR_REFUSED, where=["d.json"], outputs=["g.vdb"],
                       signal=term, timeout=60)], files=files, note=note + "; SIGTERM after 2 s"),
        ]
    # A genuinely big part: voxelize cannot hold it (out of memory, said so up front); slice streams it
    # and must answer SIGTERM; simulate is small (one rod).
    big = {"big.json": json.dumps(big_solid(), indent=1)}
    cs += [
        Case("big-solid-voxelize", [Step(["voxelize", "big.json", "-o", "g.vdb"], expect={1}, max_memory=True,
                                         where=located("big.json"), patterns=["memory"], timeout=60)],
             files=big, note="8e10 voxels: refuse with the memory it needs"),
        Case("big-solid-voxelize-default-budget", [Step(["voxelize", "big.json", "-o", "g.vdb"], expect={1},
                                                        where=["big.json", "--max-memory", "--voxel-size"],
                                                        patterns=["memory"], timeout=60)],
             files=big, note="8e10 voxels with the machine's budget, under the cap"),
        Case("big-solid-slice-sigterm", [Step(["slice", "big.json", "-o", "j.zip", "--quiet"], expect={0, 1},
                                              where=["big.json", "--max-memory"], outputs=["j.zip"], jobs=["j.zip"],
                                              max_memory=True, signal=term, timeout=60)],
             files=big, note="streams for minutes: SIGTERM after 2 s"),
        Case("big-solid-slice-sigint", [Step(["slice", "big.json", "-o", "j", "--format", "dir", "--quiet"],
                                             expect={0, 1}, where=["big.json"], outputs=["j"], jobs=["j"],
                                             signal=(signal.SIGINT, 3.0), timeout=60)],
             files=big, note="SIGINT after 3 s, folder job, default budget"),
        Case("big-coupons-sigterm", [Step(["coupons", "-o", "c.zip", "--size", "400x40x150", "--fractions", "0,0.5,1",
                                           "--gap", "5", "--quiet"], expect={0, 1, 2}, where=["--size", "--fractions"],
                                          outputs=["c.zip"], jobs=["c.zip"], signal=term, timeout=60)],
             files={}, note="three 400 x 40 x 150 mm bars: SIGTERM after 2 s"),
    ]
    # The solver's own size: a budget refusal (exit 1) or a range check (exit 2), naming what to change.
    m = {"m.json": json.dumps(cantilever(), indent=1)}
    for opt, value in [("--spans", "20000000"), ("--refine", "1000000"), ("--spans", "2000000")]:
        cs.append(Case(f"simulate{opt}-{value}", [Step(["simulate", "m.json", "-o", "out.json", opt, value], expect={1, 2},
                                                      where=[opt, "--max-memory"], timeout=60)],
                       files=m, note=f"{opt} {value} on a single cantilever"))
    cs.append(Case("simulate-spans-sigterm", [Step(["simulate", "m.json", "-o", "out.json", "--spans", "100000"],
                                                   expect={0, 1, 2}, where=["--spans", "--max-memory"],
                                                   outputs=["out.json"], signal=term, timeout=60)],
                   files=m, note="the largest --spans (0.7 M unknowns): SIGTERM after 2 s"))
    return cs
