#!/usr/bin/env python3
"""Checks the Catch2 test and section names of tests/ for what would keep a failure from being seen:
  python3 scripts/check_test_names.py [REPO=.]
- a ';' in a TEST_CASE name: CMake cuts the discovered test's name there, so ctest runs a filter that
  matches nothing (caught by --warn NoTests, but the test never runs);
- ': ' late in a name: Catch 2.13's console reporter indents the lines after the header's first ': ' by
  its column, and once that reaches the console's width its text wrapping never ends, so the failure
  of such a test hangs instead of being printed (it did at column 77 with Catch's default width of 80;
  tests/test_main.cpp now sets 160). Names must put it before column 60: a margin, and names that read
  in an 80-column terminal.
Reads the test sources git tracks, or every tests/**/*.cpp and .hpp outside a git checkout. Prints
"FILE:LINE: what" per offending name; exits 1 when any is found or no name was read, 0 otherwise."""
import pathlib
import re
import subprocess
import sys

root = sys.argv[1] if len(sys.argv) > 1 else '.'
listed = subprocess.run(['git', 'ls-files', '--cached', '--others', '--exclude-standard', 'tests/*.cpp', 'tests/*.hpp'],
                        cwd=root, capture_output=True, text=True)
files = listed.stdout.split() if listed.returncode == 0 else \
    [str(p.relative_to(root)) for p in sorted(pathlib.Path(root).glob('tests/**/*')) if p.suffix in ('.cpp', '.hpp')]
NAME = re.compile(r'\b(TEST_CASE|SECTION)\(\s*"((?:[^"\\]|\\.)*)"')
LATEST_COLON = 60
problems = []
names = 0
for path in files:
    text = open(f'{root}/{path}', encoding='utf-8').read()
    for m in NAME.finditer(text):
        kind, name = m.group(1), m.group(2)
        names += 1
        line = text.count('\n', 0, m.start()) + 1
        if kind == 'TEST_CASE' and ';' in name:
            problems.append(f"{path}:{line}: ';' in the test name {name!r} (CMake cuts it there)")
        colon = name.find(': ')
        if colon >= LATEST_COLON:
            problems.append(f"{path}:{line}: ': ' at column {colon} of {name[:70]!r}... (keep it before {LATEST_COLON}: "
                            f"Catch's wrapping of a header hangs once the column reaches the console's width)")
if names == 0:
    problems.append(f"{root}: no TEST_CASE or SECTION name found under tests/")
for p in problems:
    print(p)
sys.exit(1 if problems else 0)
