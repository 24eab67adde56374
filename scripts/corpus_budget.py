#!/usr/bin/env python3
"""Keeps a fuzz corpus within a size budget: the inputs that add the most coverage edges per byte.

    corpus_budget.py CONTROL_FILE BUDGET_BYTES OUT_DIR SEED_DIR

CONTROL_FILE is written by `FUZZER -merge=1 -use_counters=0 -merge_control_file=CONTROL_FILE ...`: it lists
every input and the edges it covers. The seeds (always replayed from SEED_DIR) cover their edges for free;
the other inputs are chosen greedily, most new edges per byte first, until the budget is spent, and copied
to OUT_DIR under the SHA-1 of their bytes (libFuzzer's names). Prints the edges kept.
"""
import hashlib
import os
import sys


def read_control(path):
    lines = open(path).read().split("\n")
    count = int(lines[0])
    files = lines[2:2 + count]
    coverage = {}
    for line in lines[2 + count:]:
        parts = line.split()
        if parts and parts[0] == "COV":
            coverage[files[int(parts[1])]] = set(map(int, parts[2:]))
    return coverage


def main():
    control, budget, out, seeds = sys.argv[1], int(sys.argv[2]), sys.argv[3], os.path.abspath(sys.argv[4])
    coverage = read_control(control)
    every = set().union(*coverage.values()) if coverage else set()
    have = set()
    candidates = {}
    for path, edges in coverage.items():
        if os.path.abspath(path).startswith(seeds + os.sep):
            have |= edges
        else:
            candidates[path] = edges
    used = 0
    os.makedirs(out, exist_ok=True)
    while True:
        best, best_score = None, 0.0
        for path, edges in candidates.items():
            size = max(1, os.path.getsize(path))
            gain = len(edges - have)
            if gain and used + size <= budget and gain / size > best_score:
                best, best_score = path, gain / size
        if best is None:
            break
        data = open(best, "rb").read()
        with open(os.path.join(out, hashlib.sha1(data).hexdigest()), "wb") as f:
            f.write(data)
        have |= candidates.pop(best)
        used += len(data)
    share = 100.0 * len(have) / len(every) if every else 100.0
    print(f"kept {len(os.listdir(out))} inputs, {used} bytes: {len(have)} of {len(every)} edges ({share:.1f}%) with the seeds")


if __name__ == "__main__":
    main()
