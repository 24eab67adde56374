#!/usr/bin/env python3
"""Checks the Catch2 test and section names of tests/ for what would keep a failure from being seen:
  python3 scripts/check_test_names.py [REPO=.]
- a ';' in a TEST_CASE name: CMake cuts the discovered test's name there, so ctest runs a filter that
  matches nothing (caught by --warn NoTests, but the test never runs);
- ': ' late in a name: Catch 2.13's console reporter indents the lines after the header's first ': ' by
  its column, and at a column of the console width (79) or more its text wrapping never ends, so the
  failure of such a test hangs instead of being printed. Names must put it before column 60 (sections
  are printed 2 further in).
Prints "FILE:LINE: what" per offending name; exits 1 when any is found, 0 otherwise."""
import re
import subprocess
import sys

root = sys.argv[1] if len(sys.argv) > 1 else '.'
files = subprocess.run(['git', 'ls-files', 'tests/*.cpp', 'tests/*.hpp'], cwd=root, capture_output=True, text=True).stdout.split()
NAME = re.compile(r'\b(TEST_CASE|SECTION)\(\s*"((?:[^"\\]|\\.)*)"')
LATEST_COLON = 60
problems = []
for path in files:
    text = open(f'{root}/{path}', encoding='utf-8').read()
    for m in NAME.finditer(text):
        kind, name = m.group(1), m.group(2)
        line = text.count('\n', 0, m.start()) + 1
        if kind == 'TEST_CASE' and ';' in name:
            problems.append(f"{path}:{line}: ';' in the test name {name!r} (CMake cuts it there)")
        colon = name.find(': ')
        if colon >= LATEST_COLON:
            problems.append(f"{path}:{line}: ': ' at column {colon} of {name[:70]!r}... (Catch hangs printing its failure "
                            f"from column ~77; keep it before {LATEST_COLON})")
for p in problems:
    print(p)
sys.exit(1 if problems else 0)
