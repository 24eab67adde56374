"""Class optimize: hostile inputs for `rodfab optimize`. Training cases and targets nested, missing,
self-referential, far too many or out of range; weights and coordinates that overflow the objective;
options out of range; signals mid-run. Every one ends with exit 0 and a valid output, 1 (bad file,
located) or 2 (bad option), or 130/143 after a signal; never a crash, a hang or a half-written file."""

from __future__ import annotations

import copy
import json
import signal

from engine import Case, Step
from fixtures import deep_object, with_deep

CASE = {"supports": [{"at": {"rod": "post", "end": "start"}, "type": "clamped"}],
        "loads": [{"at": {"rod": "arm", "end": "end"}, "force": [0.0, 0.05, -0.05], "moment": [1.0, 0, 0]}], "load_steps": 2}


def frame(target=None, **top) -> dict:
    """A post and an arm joined at its top, one load case whose target is `target` (default: the
    arm drawn lower, inline)."""
    def rod(name, a, b):
        return {"name": name, "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]},
                "section": {"shape": "circle", "diameter": 2.0}, "modulus": 60.0}
    if target is None:
        target = {"rods": {"arm": {"centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 30], [25, 5, 25]]}}}}
    d = {"format": "rodfab.design/1", "units": "mm",
         "rods": [rod("post", [0, 0, 0], [0, 0, 30]), rod("arm", [0, 0, 30], [25, 0, 30])],
         "mechanics": dict(CASE, load_cases=[dict(copy.deepcopy(CASE), name="train", target=target)])}
    d.update(top)
    return d


def run(name: str, argv: list[str], files: dict, expect, where=(), outputs=("o.json",), note="", timeout=60) -> Case:
    return Case(name, [Step(argv, expect=set(expect), where=list(where), outputs=list(outputs), timeout=timeout)],
                files={k: (v if isinstance(v, str) else json.dumps(v)) for k, v in files.items()}, note=note)


OPT = ["optimize", "d.json", "-o", "o.json", "--max-iterations", "20"]


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    ok = frame()
    cs.append(run("inline-target", OPT, {"d.json": ok}, {0}, note="a plain run: output written"))
    cs.append(run("target-is-itself", OPT, {"d.json": frame({"design": "d.json"})}, {0},
                  note="the design is its own target (the undeformed shape): reads once, no recursion"))
    cs.append(run("target-design-deep", OPT, {"d.json": frame({"design": "t.json"}), "t.json": deep_object()}, {1},
                  where=["t.json"], note="the target design nested 60,000 levels deep"))
    cs.append(run("target-design-missing", OPT, {"d.json": frame({"design": "none.json"})}, {1}, where=["target.design"]))
    cs.append(run("target-design-is-folder", OPT, {"d.json": frame({"design": "."})}, {1}, where=["target.design"]))
    cs.append(run("load-cases-deep", OPT, {"d.json": with_deep(ok, ["mechanics", "load_cases"])}, {1}, where=["load_cases"]))
    many = copy.deepcopy(ok)
    many["mechanics"]["load_cases"] = [dict(copy.deepcopy(CASE), name=f"c{i}") for i in range(10000)]
    cs.append(run("load-cases-10000", OPT, {"d.json": many}, {1}, where=["load_cases"], note="10,000 training cases"))
    no_target = copy.deepcopy(ok)
    del no_target["mechanics"]["load_cases"][0]["target"]
    cs.append(run("no-target", OPT, {"d.json": no_target}, {1}, where=["load_cases"]))
    huge_weight = copy.deepcopy(ok)
    huge_weight["mechanics"]["load_cases"][0]["weight"] = 1e308
    cs.append(run("weight-1e308", OPT, {"d.json": huge_weight}, {1}, where=["mechanics.load_cases[0].weight"],
                  note="refused by the reader (weights are 0 or 1e-6 to 1e6); g would overflow to infinity"))
    far = frame({"rods": {"arm": {"centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 30], [1e300, 0, 30]]}}}})
    cs.append(run("target-1e300", OPT, {"d.json": far}, {0, 1}, where=["d.json", "target"], note="a target 1e300 mm away"))
    tiny = frame(optimize={"bounds_mpa": [1e-300, 1e6]})
    cs.append(run("bounds-extreme", OPT, {"d.json": tiny}, {0, 1}, where=["d.json", "train", "bounds"],
                  note="bounds from 1e-300 to 1e6 MPa"))
    cs.append(run("bounds-inf", OPT, {"d.json": json.dumps(ok)[:-1] + ', "optimize": {"bounds_mpa": [8, 1e999]}}'}, {1},
                  where=["bounds_mpa", "d.json"]))
    for opt, value in [("--modulus-controls", "1"), ("--modulus-controls", "65"), ("--modulus-controls", "1e9"),
                       ("--modulus-controls", "x"), ("--max-iterations", "-2"), ("--max-iterations", "99999999999"),
                       ("--threads", "-1"), ("--calibration", "")]:
        cs.append(run(f"option{opt}-{value or 'empty'}", ["optimize", "d.json", "-o", "o.json", opt, value], {"d.json": ok},
                      {2}, where=[opt]))
    for opt, value in [("--scaling", "exp"), ("--scaling", ""), ("--render", "")]:
        cs.append(run(f"option{opt}-{value or 'empty'}", ["optimize", "d.json", "-o", "o.json", opt, value], {"d.json": ok},
                      {2}, where=[opt]))
    cs.append(run("render-is-design", OPT + ["--render", "d.json"], {"d.json": ok}, {1}, where=["d.json"], outputs=()))
    cs.append(run("render-is-folder", OPT + ["--render", "."], {"d.json": ok}, {1}, where=["."], outputs=()))
    cs.append(run("render-same-as-plot", OPT + ["--render", "p.png", "--plot", "p.png"], {"d.json": ok}, {2},
                  where=["--render"], outputs=()))
    cs.append(run("render-target-1e300", OPT + ["--render", "r.png"], {"d.json": far}, {0, 1}, where=["d.json", "target"],
                  outputs=("o.json", "r.png"), note="a target 1e300 mm away, drawn"))
    cs.append(run("output-is-target", ["optimize", "d.json", "-o", "t.json"],
                  {"d.json": frame({"design": "t.json"}), "t.json": frame()}, {1}, where=["t.json"], outputs=()))
    for sig in (signal.SIGINT, signal.SIGTERM):
        chain = frame(optimize={"modulus_controls": 64, "max_iterations": 100000, "tolerance": 0})
        cs.append(Case(f"{signal.Signals(sig).name.lower()}-mid-run",
                       [Step(["optimize", "d.json", "-o", "o.json", "--render", "r.png", "--plot", "p.png"],
                             outputs=["o.json", "r.png", "p.png"], signal=(sig, 0.6), timeout=120)],
                       files={"d.json": json.dumps(chain)}, note="interrupted while iterating"))
    return cs
