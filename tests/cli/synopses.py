"""Every command's synopsis as README.md shows it is the one `rodfab COMMAND --help` prints (built from
the command's options, slicer/options.hpp synopsisOf), and every option that takes a value names it
(no Boost "arg" placeholder), and every default is shown as written (0.05, not 0.050000000000000003).

    synopses.py RODFAB SOURCE_DIR
"""

import os
import re
import subprocess
import sys

rodfab, src = sys.argv[1], sys.argv[2]
failures = []


def run(*args):
    return subprocess.run([rodfab, *args], capture_output=True, text=True, check=True).stdout


commands = re.findall(r"^  (\S+)\s", run("--help").split("commands:\n", 1)[1], re.M)
if len(commands) < 10:
    failures.append(f"rodfab --help lists {len(commands)} commands: {commands}")

with open(os.path.join(src, "README.md"), encoding="utf-8") as f:
    readme = f.read()
# The README's code blocks as one stream of words: a synopsis may be wrapped over several lines.
code, inside = [], False
for line in readme.splitlines():
    if line.startswith("```"):
        inside = not inside
    elif inside:
        code.append(line)
words = " ".join(" ".join(code).split())


def is_synopsis_word(word):
    return word.startswith("[") or word.startswith("--") or re.match(r"^[A-Z][A-Z0-9_.|,-]*", word) is not None


for command in commands:
    help_text = run(command, "--help")
    usage = help_text.splitlines()[0]
    if not usage.startswith("usage: rodfab " + command):
        failures.append(f"{command}: --help begins {usage!r}")
        continue
    synopsis = usage[len("usage: "):]
    if re.search(r"\barg\b", help_text):
        failures.append(f"{command}: an option without a value name in --help")
    # A default shown as the binary double prints it (0.050000000000000003) instead of as written.
    for default in re.findall(r"\(=([0-9.eE+-]+)\)", help_text):
        if len(default.split(".")[-1]) > 6:
            failures.append(f"{command}: --help shows the default {default}; give default_value its text")
    at = words.find(synopsis + " ")
    if at < 0 and words.endswith(synopsis):
        at = len(words) - len(synopsis)  # the last words of the README: nothing follows
    if at < 0:
        failures.append(f"{command}: README.md does not show the synopsis of --help:\n  {synopsis}")
        continue
    rest = words[at + len(synopsis):].split()
    if rest and is_synopsis_word(rest[0]):
        failures.append(f"{command}: README.md's synopsis goes on with {rest[0]!r}, which --help does not list")

for failure in failures:
    print("FAIL:", failure)
print(f"{len(commands)} commands checked, {len(failures)} failure(s)")
sys.exit(1 if failures else 0)
