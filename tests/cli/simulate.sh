#!/usr/bin/env bash
# rodfab simulate from the command line: a cantilever rolled by an end moment lands where the
# elastica says, the output is a valid design, and bad input is named and writes nothing.
#   simulate.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

# L = 20 mm, d = 1 mm, E = 100 MPa: EI = 100 pi / 64 N mm^2. M = pi EI / (2 L) turns the tip by a
# quarter turn, onto (2L/pi, 2L/pi) = (12.7324, 12.7324).
python3 - "$tmp/roll.json" <<'PY'
import json, math, sys
EI = 100 * math.pi / 64
design = {
  "format": "rodfab.design/1", "units": "mm",
  "rods": [{"name": "beam", "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [20, 0, 0]]},
            "section": {"shape": "circle", "diameter": 1.0}, "modulus": 100.0}],
  "mechanics": {"poisson_ratio": 0.4,
                "supports": [{"at": {"rod": "beam", "end": "start"}, "type": "clamped"}],
                "loads": [{"at": {"point": [20, 0, 0]}, "moment": [0, 0, math.pi * EI / 40]}],
                "load_steps": 3}}
json.dump(design, open(sys.argv[1], "w"), indent=1)
PY
"$rodfab" simulate "$tmp/roll.json" --spans 32 -o "$tmp/rolled.json" > "$tmp/out" 2>&1 || fail "simulate: $(cat "$tmp/out")"
grep -q "^step   3  load 1.0000  Newton:" "$tmp/out" || fail "no convergence history: $(cat "$tmp/out")"
grep -q "largest displacement" "$tmp/out" || fail "no summary: $(cat "$tmp/out")"
"$rodfab" validate "$tmp/rolled.json" > /dev/null 2>&1 || fail "the deformed design does not validate"
python3 - "$tmp/rolled.json" <<'PY' || fail "deformed design content"
import json, math, sys
d = json.load(open(sys.argv[1]))
rod = d["rods"][0]
tip = rod["centerline"]["points"][-1]  # clamped knots: the last control point is the tip
expect = 40 / math.pi
assert abs(tip[0] - expect) < 1e-3 and abs(tip[1] - expect) < 1e-3 and abs(tip[2]) < 1e-9, tip
assert rod["centerline"]["degree"] == 4 and len(rod["centerline"]["points"]) == 36
assert len(rod["orientation"]["quaternions"]) == 36
assert "mechanics" not in d
PY
ls -A "$tmp" | grep -q tmp && fail "temporaries left behind: $(ls -A "$tmp")"

# The deformed design can be voxelized like any other.
"$rodfab" voxelize "$tmp/rolled.json" --voxel-size 0.1,0.1,0.1 -o "$tmp/rolled.vdb" > /dev/null 2>&1 ||
  fail "voxelize the deformed design"

# JSON summary.
"$rodfab" simulate "$tmp/roll.json" --spans 16 -o "$tmp/rolled2.json" --json > "$tmp/json" || fail "--json"
python3 - "$tmp/json" <<'PY' || fail "--json content"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["rods"] == 1 and j["supports"] == 1 and j["unknowns"] == 7 * 20, j
assert len(j["load_steps"]) == 3 and j["load_steps"][-1]["load_factor"] == 1.0
assert all(s["residuals"][-1] < 1e-6 for s in j["load_steps"])
assert abs(j["largest_displacement_mm"] - ((20 - 40 / 3.141592653589793) ** 2 + (40 / 3.141592653589793) ** 2) ** 0.5) < 1e-2
PY

# Errors: exit 1, the file and field named, nothing written.
expect_error() {  # NAME PATTERN DESIGN [OPTIONS...]
  local name=$1 pattern=$2 design=$3
  shift 3
  "$rodfab" simulate "$design" -o "$tmp/never.json" "$@" > /dev/null 2> "$tmp/err"
  [ $? -eq 1 ] || fail "$name: expected exit 1"
  grep -q -- "$pattern" "$tmp/err" || fail "$name: expected '$pattern' in: $(cat "$tmp/err")"
  [ ! -e "$tmp/never.json" ] || fail "$name: wrote an output"
}
edit() {  # OUT PYTHON-STATEMENTS (on d)
  python3 - "$tmp/roll.json" "$1" "$2" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
exec(sys.argv[3])
json.dump(d, open(sys.argv[2], "w"))
PY
}
edit "$tmp/nomech.json" 'del d["mechanics"]'
expect_error "no mechanics block" "nomech.json: mechanics: the design has no \"mechanics\" block" "$tmp/nomech.json"
edit "$tmp/nosupport.json" 'd["mechanics"]["supports"] = []'
expect_error "no support" "nosupport.json: mechanics.supports: no support" "$tmp/nosupport.json"
edit "$tmp/badrod.json" 'd["mechanics"]["loads"][0]["at"] = {"rod": "nope", "end": "end"}'
expect_error "unknown rod" "badrod.json: mechanics.loads\[0\].at.rod: no rod is named \"nope\"" "$tmp/badrod.json"
edit "$tmp/badpoint.json" 'd["mechanics"]["loads"][0]["at"] = {"point": [10, 0, 0]}'
expect_error "load off the rod ends" "badpoint.json: mechanics.loads\[0\].at.point: no rod end lies within" "$tmp/badpoint.json"
edit "$tmp/badnu.json" 'd["mechanics"]["poisson_ratio"] = 0.7'
expect_error "Poisson ratio" "badnu.json: mechanics.poisson_ratio: expected a Poisson ratio in" "$tmp/badnu.json"
edit "$tmp/pinned.json" 'd["mechanics"]["supports"][0]["type"] = "pinned"'
expect_error "a mechanism" "the structure is a mechanism" "$tmp/pinned.json"
expect_error "keeping degree 1" "rods\[0\].centerline.degree: the rod solver collocates second derivatives" "$tmp/roll.json" --degree 0
"$rodfab" simulate "$tmp/roll.json" -o "$tmp/no/such/dir/x.json" 2> "$tmp/err"
[ $? -eq 1 ] || fail "missing output folder: expected exit 1"
grep -q "x.json: cannot write" "$tmp/err" || fail "missing output folder not named: $(cat "$tmp/err")"
"$rodfab" simulate "$tmp/roll.json" -o "$tmp/x.json" --degree 1 2> /dev/null
[ $? -eq 2 ] || fail "--degree 1: expected exit 2"
"$rodfab" simulate "$tmp/roll.json" 2> /dev/null
[ $? -eq 2 ] || fail "no --output: expected exit 2"
"$rodfab" simulate --help | grep -q "usage: rodfab simulate" || fail "--help"
echo "simulate: OK"
