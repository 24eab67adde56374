#!/usr/bin/env python3
"""rodfab torture suite: hostile inputs per class of the reliability issue, each run under a memory cap
and a timeout in a fresh folder (tests/torture/engine.py says what is checked).

usage: run.py RODFAB SOURCE_DIR [CLASS ...] [--case GLOB] [--list] [--keep] [--quiet]

  CLASS       force, memory, crashes, kinks, interrupts, inspect, profiles, numerics, optimize, shapes, gcvf (default: all)
  --case GLOB run only the cases whose name matches (fnmatch), e.g. --case 'inspect-zip-*'
  --list      list the cases and exit
  --keep      keep each case's folder (printed) for a look afterwards

Environment: TORTURE_MEMORY_CAP (bytes, default 2 GiB address space), TORTURE_MAX_MEMORY (the value
passed to --max-memory where a case asks for it, default 512M), TORTURE_SIGNAL_GRACE (seconds a
signalled process may take to exit, default 1), TORTURE_TIME_SCALE (multiplies every timeout),
TORTURE_SEED (the random signal delays of the interrupt class, default 1).

Exit 0 when every selected case passes or is a known open failure (known_failures.txt; --strict counts
those too), 1 otherwise; every failing case is listed with its reasons."""

from __future__ import annotations

import fnmatch
import importlib
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import engine  # noqa: E402

INCONCLUSIVE_ATTEMPTS = 5  # runs of a case whose signal moment never came, before it is reported

CLASSES = ["force", "memory", "crashes", "kinks", "interrupts", "inspect", "profiles", "numerics", "optimize", "shapes", "gcvf"]


def load(cls: str, ctx: engine.Context) -> list[engine.Case]:
    module = importlib.import_module(f"cases_{cls}")
    cases = module.cases(ctx)
    for c in cases:
        c.group = cls
    names = [c.name for c in cases]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SystemExit(f"duplicate case names in cases_{cls}.py: {sorted(dup)}")
    return cases


def known_failures() -> dict[str, str]:
    """Cases still open in the reliability issue (known_failures.txt: `class/name  reason`). They run
    and are reported like every case; they fail their class only with --strict."""
    known = {}
    for line in (Path(__file__).parent / "known_failures.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, reason = line.partition(" ")
            known[name] = reason.strip()
    return known


def main(argv: list[str]) -> int:
    args, flags, pattern = [], set(), "*"
    it = iter(argv)
    for a in it:
        if a == "--case":
            pattern = next(it, "*")
        elif a.startswith("--"):
            flags.add(a)
        else:
            args.append(a)
    if len(args) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    rodfab, src = Path(args[0]).resolve(), Path(args[1]).resolve()
    classes = args[2:] or CLASSES
    unknown = [c for c in classes if c not in CLASSES]
    if unknown:
        print(f"run.py: unknown class {unknown}; expected some of {CLASSES}", file=sys.stderr)
        return 2
    ctx = engine.Context(rodfab, src, engine.is_sanitized(rodfab))
    try:
        selected = [c for cls in classes for c in load(cls, ctx) if fnmatch.fnmatchcase(c.name, pattern)]
        if "--list" in flags:
            for c in selected:
                print(f"{c.group:11s} {c.name:44s} {c.note}")
            return 0
        if ctx.sanitized:
            print("sanitizer build: no address-space cap; a resident-memory watchdog instead")
        failed: list[tuple[engine.Case, list[str], list[str]]] = []
        start = time.monotonic()
        for case in selected:
            t0 = time.monotonic()
            # A moment named by what appears on disk can be shorter than the 4 ms poll (a small job's
            # folder renamed right after its manifest): a run that ends before it proves nothing either
            # way, so the case runs again, up to INCONCLUSIVE_ATTEMPTS times, before it is reported.
            for attempt in range(1, INCONCLUSIVE_ATTEMPTS + 1):
                problems, log = engine.run_case(ctx, case, keep="--keep" in flags)
                if not problems or not all("inconclusive:" in p for p in problems):
                    break
            if attempt > 1:
                log.insert(0, f"  (attempt {attempt} of {INCONCLUSIVE_ATTEMPTS}: the earlier runs ended before the signal's moment)")
            verdict = "FAIL" if problems else "ok  "
            print(f"{verdict} {case.group}/{case.name} ({time.monotonic() - t0:.1f} s)", flush=True)
            if problems or "--keep" in flags:
                for line in log:
                    print(line)
            for p in problems:
                print(f"    - {p}")
            if problems:
                failed.append((case, problems, log))
        print(f"\n{len(selected) - len(failed)} of {len(selected)} cases passed in {time.monotonic() - start:.0f} s")
        known = known_failures()
        open_cases = [c for c, _, _ in failed if f"{c.group}/{c.name}" in known]
        new = [c for c, _, _ in failed if f"{c.group}/{c.name}" not in known]
        for c in open_cases:
            print(f"known failure (open): {c.group}/{c.name}: {known[f'{c.group}/{c.name}']}")
        ran = {f"{c.group}/{c.name}" for c in selected}
        fixed = [n for n in known if n in ran and n not in {f"{c.group}/{c.name}" for c, _, _ in failed}]
        for n in fixed:
            print(f"passes now, remove from known_failures.txt: {n}")
        if new:
            print("failing: " + ", ".join(f"{c.group}/{c.name}" for c in new))
        return 1 if new or (open_cases and "--strict" in flags) else 0
    finally:
        ctx.close()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
