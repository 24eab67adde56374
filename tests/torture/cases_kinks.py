"""Class 4, kinked centerlines: polylines bent by 45 degrees or more (in x-y, x-z, y-z), repeated
interior knots, extreme rational weights. They are legal designs: validate accepts them, slice must
succeed (exit 0) and `rodfab inspect` must pass the job. (Whether the voxels are exactly right is for
the Catch2 tests against the exact point-in-rod test.)"""

from __future__ import annotations

import math

from engine import Case, Step
from fixtures import bent, design, polyline, rod


def sliced(name: str, doc: str, note: str, voxelize: bool = False) -> Case:
    steps = [Step(["validate", "d.json"], where=["d.json"]),
             Step(["slice", "d.json", "-o", "j.zip", "--quiet"], outputs=["j.zip"], jobs=["j.zip"], where=["d.json"], timeout=60)]
    if voxelize:
        steps.append(Step(["voxelize", "d.json", "-o", "g.vdb"], outputs=["g.vdb"], where=["d.json"], timeout=60))
    return Case(name, steps, files={"d.json": doc}, note=note)


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    for plane in ["xy", "xz", "yz"]:
        for angle in [30, 45, 60, 90, 120, 150, 170]:
            cs.append(sliced(f"polyline-{plane}-{angle}", design(polyline(bent(angle, plane))),
                             f"a degree-1 polyline bent by {angle} degrees in {plane}", voxelize=angle in (45, 90)))
    # Sections other than circles (the frame jumps at the kink), flat caps, a kink at a modulus knot.
    ell = {"shape": "ellipse", "width": 1.2, "height": 0.6}
    rect = {"shape": "rectangle", "width": 1.0, "height": 0.5}
    cs += [
        sliced("ellipse-xy-90", design(polyline(bent(90, "xy"), section=ell, normal=[0, 0, 1])), "an ellipse bent 90 degrees in x-y"),
        sliced("rectangle-xz-90", design(polyline(bent(90, "xz"), section=rect, normal=[0, 1, 0])),
               "a rectangle bent 90 degrees in x-z"),
        sliced("rectangle-xz-135", design(polyline(bent(135, "xz"), section=rect, normal=[0, 1, 0])),
               "a rectangle bent 135 degrees in x-z"),
        sliced("flat-caps-xy-90", design(polyline(bent(90, "xy"), caps="flat")), "flat caps, 90 degrees"),
        sliced("modulus-knot-at-kink", design(polyline(bent(60, "xz"), modulus={"degree": 1, "knots": [0, 0, 0.5, 1, 1],
                                                                              "values": [8, 190, 8]})),
               "E(s) peaks at the kink"),
        sliced("zigzag-3d", design(polyline([[0, 0, 0], [3, 0, 0], [3, 3, 0], [3, 3, 3], [0, 3, 3], [0, 0, 3], [0, 0, 6]])),
               "six segments turning 90 degrees about x, y and z in turn"),
        sliced("zigzag-sharp", design(polyline([[i * 0.8, 3.0 * (i % 2), 0.0] for i in range(9)], diameter=0.6)),
               "eight segments with 150-degree turns"),
        sliced("helix-polyline", design(polyline([[4 * math.cos(i * math.pi / 3), 4 * math.sin(i * math.pi / 3), 0.6 * i]
                                                  for i in range(13)], diameter=0.8)),
               "a hexagonal helix: 60-degree kinks out of plane"),
        sliced("short-segments", design(polyline([[0, 0, 0], [2, 0, 0], [2.05, 0.05, 0], [2.05, 2, 0]])),
               "two 90-degree turns 0.07 mm apart (shorter than the radius)"),
        sliced("two-rods-joint", design(polyline(bent(90, "xy"), name="a"),
                                        polyline([[3, 0, 0], [3, 0, 3], [0, 0, 3]], name="b")),
               "two kinked rods meeting at a point"),
    ]
    # Smooth-looking NURBS that are kinked: repeated interior knots, weights pulling to a corner.
    corner = [[0, 0, 0], [1.5, 0, 0], [3, 0, 0], [3, 1.5, 0], [3, 3, 0]]
    cs += [
        sliced("double-knot-cubic", design(rod("dk", [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [3, 1, 0], [3, 2, 0]], degree=3,
                                               knots=[0, 0, 0, 0, 0.5, 0.5, 1, 1, 1, 1])),
               "a cubic with a double interior knot at a corner (C1 lost)"),
        sliced("triple-knot-cubic", design(rod("tk", [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [3, 1, 0], [3, 2, 0], [3, 3, 0]],
                                               degree=3, knots=[0, 0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1, 1])),
               "a cubic with a triple interior knot: a true 90-degree kink"),
        sliced("triple-knot-cubic-xz", design(rod("tkz", [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [2, 0, 1], [1, 0, 2], [0, 0, 3]],
                                                  degree=3, knots=[0, 0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1, 1])),
               "a 135-degree kink in x-z from a triple knot"),
        sliced("double-knot-quadratic", design(rod("dq", corner, degree=2, knots=[0, 0, 0, 0.5, 0.5, 1, 1, 1])),
               "a quadratic with a double interior knot: a kink"),
        sliced("weights-corner-1e4", design(rod("wc", [[0, 0, 0], [3, 0, 0], [3, 3, 0]], degree=2, weights=[1, 1e4, 1])),
               "a quadratic pulled into its corner by a weight of 1e4"),
        sliced("weights-corner-1e6-xz", design(rod("wz", [[0, 0, 0], [3, 0, 0], [3, 0, 3]], degree=2, weights=[1, 1e6, 1])),
               "the same in x-z with a weight of 1e6"),
        sliced("weights-extreme-cubic", design(rod("we", [[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0]], degree=3,
                                                   weights=[1, 1e3, 1e3, 1])),
               "the README's rod with weights [1, 1e3, 1e3, 1]"),
    ]
    return cs
