"""Class 5, interrupts: SIGINT/SIGTERM at any moment ends every command with 130/143 and leaves nothing
(or, if the work was already complete, exit 0 with complete, valid outputs: never anything between).
Each case first runs the command uninterrupted (its duration sets the scale of the delays), then
signals copies of it at random moments (TORTURE_SEED), at the moments the staging appears and the
job is being finished, and with SIGKILL: a later run into the same folder must clean the dead run's
hidden staging, without touching a run that is still alive."""

from __future__ import annotations

import json
import os
import random
import signal
from pathlib import Path

from engine import Case, Fraction, Step
from fixtures import cantilever, csv_rows, dma_rows

SEED = int(os.environ.get("TORTURE_SEED", "1"))
RANDOM_DELAYS = 5
MIN_DELAY = 0.3  # the program's start-up (loading its libraries) takes ~0.1 s on the reference machine


def new_entry(hidden: bool | None = None, suffix: str = "", inside: str | None = None):
    """A trigger: an entry appeared in the case folder that was not there when the step started (hidden
    or not, with the given suffix), or (inside) a file matching that glob appeared in such a new folder. The
    first poll, a few milliseconds after the start, takes the "before" listing."""
    before: set[str] | None = None

    def fired(folder: Path) -> bool:
        nonlocal before
        names = set(os.listdir(folder))
        if before is None:
            before = names
            return False
        for name in names - before:
            if hidden is not None and name.startswith(".") != hidden:
                continue
            if inside is not None:
                if (folder / name).is_dir() and any((folder / name).glob(inside)):
                    return True
                continue
            if name.endswith(suffix):
                return True
        return False
    return fired


def delays(name: str, n: int) -> list[float]:
    rng = random.Random(f"{SEED}:{name}")
    # fractions of the uninterrupted run: the whole run, a little past its end, and never the first 0.3 s
    return sorted(rng.uniform(0.0, 1.1) for _ in range(n))


def interrupted(name: str, argv_for, ref_outputs: list[str], files: dict, jobs: bool, note: str,
                triggers: list[tuple[str, object]], ext: str) -> list[Case]:
    """argv_for(out) -> argv writing `out`; the outputs are out (+ extra outputs named by argv_for)."""
    cases = []
    sigs = [signal.SIGINT, signal.SIGTERM]
    ref = Step(argv_for("ref" + ext), outputs=ref_outputs, jobs=ref_outputs[:1] if jobs else [], timeout=120)
    steps = [ref]
    for i, f in enumerate(delays(name, RANDOM_DELAYS)):
        out = f"run{i}{ext}"
        argv = argv_for(out)
        # A command without an output file (dither-report) writes none, also when it finishes before the
        # signal's moment (as it did on a loaded CI machine: "output run4 missing after success").
        outs = ([out] if out in argv else []) + [a for a in argv if a.startswith(f"run{i}-")]
        steps.append(Step(argv, outputs=outs, jobs=[out] if jobs else [], timeout=120,
                          signal=(sigs[i % 2], Fraction(f, at_least=MIN_DELAY))))
    cases.append(Case(f"{name}-random", steps, files=files, note=f"{note}: {RANDOM_DELAYS} random moments"))
    for tname, (signum, trig) in triggers:
        out = f"t{ext}"
        argv = argv_for(out)
        outs = ([out] if out in argv else []) + [a for a in argv if a.startswith("t-")]
        step = Step(argv, outputs=outs, jobs=[out] if jobs else [], timeout=120, signal=(signum, trig))
        # a moment given as a fraction of the run needs the uninterrupted run first
        steps = [ref, step] if isinstance(trig, Fraction) else [step]
        cases.append(Case(f"{name}-{tname}", steps, files=files, note=f"{note}: {tname}"))
    return cases


def cases(ctx) -> list[Case]:
    ex = "{examples}"
    cs: list[Case] = []
    def early_hidden():
        return new_entry(hidden=True)

    def zip_finishing():
        # libzip assembles the job as job.zip.XXXXXX inside the staging folder, then job.zip is verified.
        return new_entry(hidden=True, inside="job.zip*")

    def dir_finishing():
        return new_entry(hidden=True, inside="job/manifest.json")

    def any_new():
        return new_entry()

    cs += interrupted("slice-zip", lambda o: ["slice", f"{ex}/buckling-spring.json", "-o", o, "--quiet"], ["ref.zip"], {}, True,
                      "slice buckling-spring to a zip", [
                          ("sigint-at-staging", (signal.SIGINT, early_hidden())),
                          ("sigterm-while-zipping", (signal.SIGTERM, zip_finishing())),
                          ("sigint-at-end", (signal.SIGINT, Fraction(0.97, at_least=MIN_DELAY))),
                      ], ".zip")
    cs += interrupted("slice-dir", lambda o: ["slice", f"{ex}/buckling-spring.json", "-o", o, "--format", "dir", "--quiet"],
                      ["ref"], {}, True, "slice buckling-spring to a folder", [
                          ("sigterm-at-staging", (signal.SIGTERM, early_hidden())),
                          ("sigint-at-manifest", (signal.SIGINT, dir_finishing())),
                          ("sigterm-at-end", (signal.SIGTERM, Fraction(0.98, at_least=MIN_DELAY))),
                      ], "")
    cs += interrupted("coupons-zip", lambda o: ["coupons", "-o", o, "--quiet"], ["ref.zip"], {}, True,
                      "the default coupon job", [
                          ("sigterm-while-zipping", (signal.SIGTERM, zip_finishing())),
                      ], ".zip")
    cs += interrupted("coupons-dir", lambda o: ["coupons", "-o", o, "--format", "dir", "--quiet"], ["ref"], {}, True,
                      "the default coupon job as a folder", [
                          ("sigint-at-manifest", (signal.SIGINT, dir_finishing())),
                      ], "")
    cs += interrupted("voxelize", lambda o: ["voxelize", f"{ex}/arm-cast.json", "-o", o], ["ref.vdb"], {}, False,
                      "voxelize arm-cast (46 MB grid)", [
                          ("sigint-while-writing", (signal.SIGINT, new_entry())),
                          ("sigterm-while-writing", (signal.SIGTERM, new_entry())),
                      ], ".vdb")
    # Long enough (~3 s) that a solve which does not poll is ended by the watchdog, which is a failure.
    m = {"m.json": json.dumps(cantilever(steps=20), indent=1)}
    cs += interrupted("simulate", lambda o: ["simulate", "m.json", "-o", o, "--spans", "4000"], ["ref.json"], m, False,
                      "simulate a 4000-span cantilever in 20 load steps", [
                          ("sigint-while-writing", (signal.SIGINT, any_new())),
                      ], ".json")
    # No output file: a report on stdout, whose low-pass measurements take seconds (the watchdog ended
    # them before they polled).
    cs += interrupted("dither-report", lambda o: ["dither-report", "--block", "96x96x96", "--dither", "white"], [], {}, False,
                      "dither-report on a 96^3 block", [], "")
    data = {"data.csv": csv_rows(dma_rows(1600))}
    cs += interrupted("calibrate", lambda o: ["calibrate", "data.csv", "-o", o, "--plot", _plot(o)],
                      ["ref.json", "ref-fit.png"], data, False, "calibrate 1,600 rows with a plot", [
                          ("sigterm-while-writing", (signal.SIGTERM, any_new())),
                      ], ".json")

    # SIGKILL leaves staging behind; the next run into the same folder (another name) must clean it.
    def killed_then(name: str, argv_kill, argv_next, outputs_next: list[str], when, files=None, note=""):
        return Case(name, [
            Step(argv_kill, signal=(signal.SIGKILL, when), timeout=120),
            Step(argv_next, outputs=outputs_next, jobs=[o for o in outputs_next if not o.endswith((".vdb", ".json"))],
                 timeout=120)], files=files or {}, note=note)

    half = Fraction(0.5)
    cs += [
        Case("slice-zip-sigkill-ref", [Step(["slice", f"{ex}/buckling-spring.json", "-o", "ref.zip", "--quiet"], outputs=["ref.zip"],
                                            jobs=["ref.zip"], timeout=120),
                                       Step(["slice", f"{ex}/buckling-spring.json", "-o", "dead.zip", "--quiet"],
                                            signal=(signal.SIGKILL, half), timeout=120),
                                       Step(["slice", f"{ex}/unfolding-box.json", "-o", "next.zip", "--quiet"],
                                            outputs=["next.zip"], jobs=["next.zip"], timeout=120)],
             note="SIGKILL half-way through a zip job, then a job to another name"),
        Case("slice-dir-sigkill-ref", [Step(["slice", f"{ex}/buckling-spring.json", "-o", "ref", "--format", "dir", "--quiet"],
                                            outputs=["ref"], jobs=["ref"], timeout=120),
                                       Step(["slice", f"{ex}/buckling-spring.json", "-o", "dead", "--format", "dir",
                                             "--quiet"], signal=(signal.SIGKILL, half), timeout=120),
                                       Step(["slice", f"{ex}/unfolding-box.json", "-o", "next", "--format", "dir", "--quiet"],
                                            outputs=["next"], jobs=["next"], timeout=120)],
             note="SIGKILL half-way through a folder job, then a job to another name"),
        killed_then("slice-sigkill-at-staging", ["slice", f"{ex}/buckling-spring.json", "-o", "dead.zip", "--quiet"],
                    ["slice", f"{ex}/unfolding-box.json", "-o", "next.zip", "--quiet"], ["next.zip"], early_hidden(),
                    note="SIGKILL as soon as the staging exists"),
        killed_then("slice-sigkill-while-zipping", ["slice", f"{ex}/buckling-spring.json", "-o", "dead.zip", "--quiet"],
                    ["slice", f"{ex}/unfolding-box.json", "-o", "next", "--format", "dir", "--quiet"], ["next"],
                    zip_finishing(), note="SIGKILL while the zip is assembled; the next job is a folder"),
        killed_then("slice-sigkill-same-name", ["slice", f"{ex}/buckling-spring.json", "-o", "job.zip", "--quiet"],
                    ["slice", f"{ex}/unfolding-box.json", "-o", "job.zip", "--quiet"], ["job.zip"], early_hidden(),
                    note="SIGKILL, then a job to the same name"),
        killed_then("coupons-sigkill", ["coupons", "-o", "dead.zip", "--quiet"],
                    ["coupons", "-o", "next.zip", "--fractions", "0,1", "--size", "5x2x0.3", "--quiet"], ["next.zip"],
                    early_hidden(), note="SIGKILL a coupon job, then another coupon job"),
        killed_then("slice-after-coupons-sigkill", ["coupons", "-o", "dead", "--format", "dir", "--quiet"],
                    ["slice", f"{ex}/unfolding-box.json", "-o", "next.zip", "--quiet"], ["next.zip"], early_hidden(),
                    note="SIGKILL a coupon folder job, then a slice"),
        killed_then("voxelize-sigkill-while-writing", ["voxelize", f"{ex}/arm-cast.json", "-o", "dead.vdb"],
                    ["voxelize", f"{ex}/unfolding-box.json", "-o", "next.vdb", "--voxel-size", "0.1,0.1,0.1"],
                    ["next.vdb"], new_entry(),
                    note="SIGKILL while the grid is written, then a grid to another name"),
        # A run that is alive must keep its staging: the other run's cleaning spares live processes.
        Case("slice-concurrent-runs", [
            Step(["slice", f"{ex}/arm-cast.json", "-o", "slow.zip", "--quiet", "--threads", "1"], outputs=["slow.zip"],
                 jobs=["slow.zip"], background=True, start_when=early_hidden(), timeout=180),
            Step(["slice", f"{ex}/unfolding-box.json", "-o", "fast.zip", "--quiet", "--threads", "1"],
                 outputs=["fast.zip"], jobs=["fast.zip"], timeout=120)],
             note="two jobs in one folder at once: both complete"),
        Case("slice-concurrent-after-sigkill", [
            Step(["slice", f"{ex}/buckling-spring.json", "-o", "dead", "--format", "dir", "--quiet"],
                 signal=(signal.SIGKILL, early_hidden()), timeout=120),
            Step(["slice", f"{ex}/arm-cast.json", "-o", "slow.zip", "--quiet", "--threads", "1"], outputs=["slow.zip"],
                 jobs=["slow.zip"], background=True, start_when=new_entry(hidden=True), timeout=180),
            Step(["slice", f"{ex}/unfolding-box.json", "-o", "fast.zip", "--quiet", "--threads", "1"],
                 outputs=["fast.zip"], jobs=["fast.zip"], timeout=120)],
             note="a dead run's staging is cleaned, a live run's is not"),
    ]
    return cs


def _plot(out: str) -> str:
    return out[:-len(".json")] + "-fit.png"
