#!/usr/bin/env python3
"""Lists the C++ functions (and Catch2 TEST_CASEs) of the tracked tree longer than LIMIT lines, longest
first: the check behind "functions short enough to read at once (< ~80 lines)".
  python3 scripts/long_functions.py [LIMIT=80] [REPO=.]
Prints "LINES FILE:LINE NAME" per function; exits 1 when any is found, 0 otherwise.
A brace counter, not a parser: comments, string, raw-string and character literals are blanked out,
then a '{' opens a function body when what precedes it ends with ')' (after qualifiers such as const,
noexcept, override, -> type) or with a constructor's initializer list, and the name before the '(' is
not a control keyword. Only outermost bodies count (a lambda inside a function belongs to it). Lambdas
without a parameter list at namespace scope and macros that hide braces are not seen."""
import os
import re
import subprocess
import sys
LIMIT = int(sys.argv[1]) if len(sys.argv) > 1 else 80
root = sys.argv[2] if len(sys.argv) > 2 else '.'
files = subprocess.run(['git', 'ls-files', '*.cpp', '*.hpp'], cwd=root, capture_output=True, text=True).stdout.split()

def strip(src):
    out = []; i = 0; n = len(src)
    while i < n:
        c = src[i]
        if src.startswith('//', i):
            j = src.find('\n', i); j = n if j < 0 else j; out.append(' ' * (j - i)); i = j
        elif src.startswith('/*', i):
            j = src.find('*/', i + 2); j = n if j < 0 else j + 2
            out.append(''.join(ch if ch == '\n' else ' ' for ch in src[i:j])); i = j
        elif c == 'R' and src.startswith('R"', i):
            m = re.match(r'R"([^(\s]*)\(', src[i:])
            if m:
                end = ')' + m.group(1) + '"'; j = src.find(end, i + m.end()); j = n if j < 0 else j + len(end)
                out.append(''.join(ch if ch == '\n' else ' ' for ch in src[i:j])); i = j
            else: out.append(c); i += 1
        elif c == '"' or (c == "'" and not (i > 0 and (src[i-1].isalnum()))):
            j = i + 1
            while j < n and src[j] != c:
                j += 2 if src[j] == '\\' else 1
            out.append(''.join(ch if ch == '\n' else ' ' for ch in src[i:j+1])); i = j + 1
        else: out.append(c); i += 1
    return ''.join(out)

CONTROL = {'constexpr', 'if', 'for', 'while', 'switch', 'catch', 'return', 'sizeof', 'decltype', 'alignof', 'noexcept'}
found = []
for f in files:
    try: src = strip(open(os.path.join(root, f), encoding='utf-8', errors='replace').read())
    except OSError: continue
    stack = []  # (kind, name, line)
    line = 1
    for i, c in enumerate(src):
        if c == '\n': line += 1
        elif c == '{':
            kind, name = 'block', ''
            head = src[max(0, i - 600):i]
            # strip trailing qualifiers
            h = re.sub(r'(\s|const|noexcept|override|final|mutable|->\s*[\w:<>,\s&*]+)*$', '', head)
            # constructor initializer list: ") : a(b), c{d}" -> find ')' before ':'
            m = re.search(r'\)\s*:\s*[\w:]+\s*[({][^;{}]*$', head)
            if h.endswith(')') or m:
                # find matching '(' to get the name
                k = len(h) - 1 if h.endswith(')') else None
                if k is not None:
                    depth = 0
                    while k >= 0:
                        if h[k] == ')': depth += 1
                        elif h[k] == '(':
                            depth -= 1
                            if depth == 0: break
                        k -= 1
                    nm = re.search(r'([~\w:<>]+|\])\s*$', h[:k]) if k >= 0 else None
                    name = nm.group(1) if nm else '?'
                else:
                    name = 'ctor'
                base = name.split('::')[-1]
                if base not in CONTROL and name != '?':
                    kind = 'func'
            stack.append((kind, name, line))
        elif c == '}':
            if not stack: continue
            kind, name, start = stack.pop()
            if kind == 'func' and not any(k == 'func' for k, _, _ in stack):
                length = line - start + 1
                if length > LIMIT:
                    found.append((length, f'{length:5d} {f}:{start} {name}'))
for _, line in sorted(found, reverse=True):
    print(line)
sys.exit(1 if found else 0)
