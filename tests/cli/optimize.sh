#!/usr/bin/env bash
# rodfab optimize from the command line: a frame whose target is its own shape under a graded
# modulus (simulated by rodfab simulate) is optimized from a uniform modulus until it matches; the
# output keeps the mechanics and optimize blocks, stays within the calibration's range and slices
# without a single clamped voxel; bad input, a case that cannot converge and interrupts write nothing.
#   optimize.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

# A post clamped at its foot and an arm joined to its top; the arm's end is pushed and twisted.
# graded.json has E(u) as cubic B-splines between 20 and 150 MPa; start.json is the same frame at
# a uniform 60 MPa with the training case whose target is graded.json's deformed shape.
python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
def rod(name, a, b, E):
    pts = [[a[k] + (b[k] - a[k]) * i / 3 for k in range(3)] for i in range(4)]
    return {"name": name, "centerline": {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "points": pts},
            "section": {"shape": "circle", "diameter": 3.0}, "modulus": E}
case = {"supports": [{"at": {"rod": "post", "end": "start"}, "type": "clamped"}],
        "loads": [{"at": {"rod": "arm", "end": "end"}, "force": [0.0, 0.15, -0.1], "moment": [2.0, 0, 0]}]}
graded = {"format": "rodfab.design/1", "units": "mm",
          "rods": [rod("post", [0, 0, 0], [0, 0, 50], {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "values": [150, 40, 90, 20]}),
                   rod("arm", [0, 0, 50], [40, 0, 50], {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "values": [30, 120, 60, 140]})],
          "mechanics": dict(case, load_steps=4)}
json.dump(graded, open(tmp + "/graded.json", "w"))
start = {"format": "rodfab.design/1", "units": "mm",
         "rods": [rod("post", [0, 0, 0], [0, 0, 50], 60.0), rod("arm", [0, 0, 50], [40, 0, 50], 60.0)],
         "mechanics": dict(case, load_steps=4, load_cases=[dict(case, name="push", target={"design": "target.json"})]),
         "optimize": {"curvature_weight": 0.5, "max_iterations": 300, "tolerance": 1e-9}}
json.dump(start, open(tmp + "/start.json", "w"))
PY
"$rodfab" simulate "$tmp/graded.json" -o "$tmp/target.json" > "$tmp/out" 2>&1 || fail "simulate the target: $(cat "$tmp/out")"

"$rodfab" optimize "$tmp/start.json" -o "$tmp/optimized.json" --plot "$tmp/history.png" --render "$tmp/shapes.png" > "$tmp/out" 2>&1 ||
  fail "optimize: $(cat "$tmp/out")"
grep -q '^stability: case "push": stable$' "$tmp/out" || fail "no stability of the case at the optimum: $(cat "$tmp/out")"
# The render, decoded by tests/cli/png_pixels.py (zlib and the PNG filters, not cairo's code): one
# load case, three columns (target, start, optimized) of three 300-pixel views; the columns differ;
# the target is drawn in one blue, the uniform start in the one colour of 60 MPa on viridis between
# the bounds, and the optimized rods in colours of viridis within the range of its moduli.
python3 - "$tmp/shapes.png" "$tmp/optimized.json" "$src/tests/cli" <<'PY' || fail "shape render"
import json, re, sys
sys.path.insert(0, sys.argv[3])
from png_pixels import pixels
from collections import Counter
w, h, px, text = pixels(sys.argv[1])
assert (w, h) == (1050, 44 + 20 + 30 + 3 * 324), (w, h)
assert list(text) == ["Software"] and re.fullmatch(r"rodfab optimize, xxh128 [0-9a-f]{32}", text["Software"]), text
STOPS = [(0.267, 0.005, 0.329), (0.278, 0.175, 0.483), (0.231, 0.322, 0.546), (0.173, 0.449, 0.558), (0.128, 0.567, 0.551),
         (0.153, 0.683, 0.503), (0.361, 0.785, 0.388), (0.680, 0.860, 0.201), (0.993, 0.906, 0.144)]  # matplotlib's viridis
def viridis(t):
    x = min(max(t, 0.0), 1.0) * 8
    i = min(int(x), 7)
    return tuple(255 * (STOPS[i][k] + (x - i) * (STOPS[i + 1][k] - STOPS[i][k])) for k in range(3))
def near(a, b, tol=4.0):
    return max(abs(a[k] - b[k]) for k in range(3)) <= tol
def column(col):  # every pixel of the column's three panels
    x0, out = 20 + col * 300 + 2, []
    for v in range(3):
        y0 = 44 + 30 + 24 + v * 324
        out += [px[y][x] for y in range(y0, y0 + 296) for x in range(x0, x0 + 296)]
    return out
BACKGROUND, GHOST, BLUE = (249, 249, 249), (209, 214, 230), (51, 89, 204)
cols = [column(c) for c in range(3)]
for a, b in [(0, 1), (0, 2), (1, 2)]:
    differ = sum(1 for p, q in zip(cols[a], cols[b]) if p != q)
    assert differ > 500, (a, b, differ)
def pale(p):  # the background, the pale target and their antialiased blends (the segment between them)
    d = [GHOST[k] - BACKGROUND[k] for k in range(3)]
    t = min(max(sum((p[k] - BACKGROUND[k]) * d[k] for k in range(3)) / sum(x * x for x in d), 0.0), 1.0)
    return near(p, [BACKGROUND[k] + t * d[k] for k in range(3)], 6)
def rod_colours(pixels_):  # the colours of the rods' cores: frequent, not pale
    counts = Counter(p for p in pixels_ if not pale(p))
    return [c for c, n in counts.most_common() if n >= 40]
target = rod_colours(cols[0])
assert target and all(near(c, BLUE, 3) for c in target), target
start = rod_colours(cols[1])
assert start and all(near(c, viridis((60 - 8) / 182)) for c in start), (start, viridis((60 - 8) / 182))
values = [v for r in json.load(open(sys.argv[2]))["rods"] for v in r["modulus"]["values"]]
lo, hi = (min(values) - 8) / 182, (max(values) - 8) / 182
optimized = rod_colours(cols[2])
ts = [lo + (hi - lo) * k / 400 for k in range(401)]
assert len(optimized) >= 3, optimized
for c in optimized:
    assert any(near(c, viridis(t)) for t in ts), (c, lo, hi)
PY
# The plot: a 960 x 640 RGB PNG tagged as ours, its image data complete (decoded here with zlib).
python3 - "$tmp/history.png" <<'PY' || fail "convergence plot"
import re, struct, sys, zlib
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n"
chunks, at = {}, 8
while at < len(data):
    n, = struct.unpack(">I", data[at:at + 4])
    kind = data[at + 4:at + 8]
    chunks.setdefault(kind, b"")
    chunks[kind] += data[at + 8:at + 8 + n]
    at += 12 + n
w, h, depth, color = struct.unpack(">IIBB", chunks[b"IHDR"][:10])
assert (w, h, depth, color) == (960, 640, 8, 2), (w, h, depth, color)
assert re.fullmatch(rb"Software\0rodfab optimize, xxh128 [0-9a-f]{32}", chunks[b"tEXt"]), chunks[b"tEXt"]
raw = zlib.decompress(chunks[b"IDAT"])
assert len(raw) == h * (1 + 3 * w)
PY
grep -q "^design:    .*: 2 rods, 1 load cases, .* unknowns per case, 8 design variables, E in \[8, 190\] MPa" "$tmp/out" ||
  fail "no header: $(cat "$tmp/out")"
grep -q "^iter    0  g/g0 1.0000e+00  |Pg| " "$tmp/out" || fail "no progress lines: $(cat "$tmp/out")"
grep -q "^iter    5  g/g0 " "$tmp/out" || fail "fewer than 5 iterations: $(cat "$tmp/out")"
grep -q "^wrote:     $tmp/optimized.json" "$tmp/out" || fail "no summary: $(cat "$tmp/out")"
"$rodfab" validate "$tmp/optimized.json" > /dev/null 2>&1 || fail "the optimized design does not validate"
python3 - "$tmp/optimized.json" <<'PY' || fail "optimized design content"
import json, sys
d = json.load(open(sys.argv[1]))
for rod in d["rods"]:
    m = rod["modulus"]
    assert m["degree"] == 3 and len(m["values"]) == 4, m
    assert all(8 <= v <= 190 for v in m["values"]), m
    assert rod["centerline"]["degree"] == 3 and len(rod["centerline"]["points"]) == 4  # the design's own geometry
assert d["mechanics"]["load_cases"][0]["name"] == "push"
assert d["mechanics"]["load_cases"][0]["target"] == {"design": "target.json"}
assert d["optimize"]["curvature_weight"] == 0.5
PY

# --json: the summary, and a target matched to the discretization error (the target was simulated
# on another basis, so not to rounding).
"$rodfab" optimize "$tmp/start.json" -o "$tmp/optimized.json" --json --modulus-controls 4 > "$tmp/summary.json" 2> "$tmp/err" ||
  fail "optimize --json: $(cat "$tmp/err")"
python3 - "$tmp/summary.json" <<'PY' || fail "--json summary: $(cat "$tmp/summary.json")"
import json, sys
s = json.load(open(sys.argv[1]))
for key in ["objective_initial", "objective_final", "iterations", "design_variables", "seconds", "cases", "rods", "unknowns"]:
    assert key in s, key
assert s["design_variables"] == 8 and s["rods"] == 2
assert s["objective_final"] / s["objective_initial"] < 1e-4, s["relative"]
assert s["cases"][0]["name"] == "push" and abs(s["cases"][0]["objective_final"] - s["objective_final"]) < 1e-12
assert s["bounds_mpa"] == [8, 190] and s["scaling"] == "log"
assert isinstance(s["line_search_fallbacks"], int) and s["line_search_fallbacks"] >= 0
estimate = s["cases"][0]["error_estimate"]  # the equilibrium's accuracy at the optimum
assert estimate["available"] and 0 < estimate["relative"] < 1e-2 and s["error_estimate_relative"] == estimate["relative"], estimate
assert s["cases"][0]["stability"] == "stable" and s["cases"][0]["critical_points"] == [], s["cases"][0]  # the load path at the optimum
assert len(s["history"]) == s["iterations"] + 1
PY

# --start uniform: one E everywhere (the geometric mean of the bounds, or as given), g0 for it;
# --method mma/ccsaq: NLopt's, one evaluation an iteration, g falls and the bounds hold.
for start in uniform uniform=60; do
  "$rodfab" optimize "$tmp/start.json" -o "$tmp/variant.json" --start "$start" --max-iterations 30 --json > "$tmp/summary.json" 2> "$tmp/err" ||
    fail "optimize --start $start: $(cat "$tmp/err")"
  python3 - "$tmp/summary.json" "$start" <<'PY' || fail "--start $start summary: $(cat "$tmp/summary.json")"
import json, math, sys
s, start = json.load(open(sys.argv[1])), sys.argv[2]
want = math.sqrt(8 * 190) if start == "uniform" else 60.0
assert abs(s["start"]["uniform_mpa"] - want) < 1e-9 * want, s["start"]
assert s["objective_final"] < 1e-2 * s["objective_initial"], s["relative"]
PY
done
for method in mma ccsaq; do
  "$rodfab" optimize "$tmp/start.json" -o "$tmp/variant.json" --method "$method" --max-iterations 40 --json > "$tmp/summary.json" 2> "$tmp/err" ||
    fail "optimize --method $method: $(cat "$tmp/err")"
  python3 - "$tmp/summary.json" "$method" <<'PY' || fail "--method $method summary: $(cat "$tmp/summary.json")"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["method"] == sys.argv[2] and s["evaluations"] <= 41 and s["iterations"] == s["evaluations"] - 1, s
assert s["objective_final"] < 1e-2 * s["objective_initial"], s["relative"]
assert 8 <= s["modulus_range_mpa"][0] and s["modulus_range_mpa"][1] <= 190
PY
done
rm -f "$tmp/variant.json"

# The same output, byte for byte, on 1 and 2 threads.
"$rodfab" optimize "$tmp/start.json" -o "$tmp/one.json" --threads 1 > /dev/null 2>&1 || fail "optimize --threads 1"
"$rodfab" optimize "$tmp/start.json" -o "$tmp/two.json" --threads 2 > /dev/null 2>&1 || fail "optimize --threads 2"
cmp -s "$tmp/one.json" "$tmp/two.json" || fail "the output depends on the thread count"
rm -f "$tmp/one.json" "$tmp/two.json"

# The optimized design slices as it is: every modulus inside the calibration's range.
"$rodfab" slice "$tmp/optimized.json" -o "$tmp/job.zip" > "$tmp/out" 2>&1 || fail "slice: $(cat "$tmp/out")"
grep -q "^clamped moduli: 0 below the floor, 0 above the stiffest mix" "$tmp/out" || fail "clamped voxels: $(cat "$tmp/out")"

# The bundled unfolding box with its published target (folded closed), a short run: g decreases,
# the accuracy is reported, and the output slices without a clamped voxel (the README's walkthrough).
"$rodfab" optimize "$src/examples/unfolding-box.json" -o "$tmp/box.json" --max-iterations 3 --json > "$tmp/box-summary.json" 2> "$tmp/err" ||
  fail "optimize the box: $(cat "$tmp/err")"
python3 - "$tmp/box-summary.json" <<'PY' || fail "box summary: $(cat "$tmp/box-summary.json")"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["rods"] == 34 and s["design_variables"] == 136 and s["iterations"] == 3, s
assert s["cases"][0]["name"] == "fold" and s["objective_final"] < 0.9 * s["objective_initial"], s["relative"]
assert s["cases"][0]["error_estimate"]["available"] and s["error_estimate_relative"] < 1e-3
PY
"$rodfab" slice "$tmp/box.json" -o "$tmp/box-job.zip" > "$tmp/out" 2>&1 || fail "slice the box: $(cat "$tmp/out")"
grep -q "^clamped moduli: 0 below the floor, 0 above the stiffest mix" "$tmp/out" || fail "box clamped voxels: $(cat "$tmp/out")"
rm -f "$tmp/box.json" "$tmp/box-job.zip"

# Errors name what is wrong and write nothing.
rm -f "$tmp/optimized.json"
expect_failure() {  # CODE FRAGMENT ARGS...
  local code=$1 fragment=$2
  shift 2
  "$rodfab" optimize "$@" > "$tmp/out" 2>&1
  local got=$?
  [ "$got" -eq "$code" ] || fail "exit $got (expected $code) for $*: $(cat "$tmp/out")"
  grep -qF -- "$fragment" "$tmp/out" || fail "no '$fragment' for $*: $(cat "$tmp/out")"
  [ -e "$tmp/optimized.json" ] && fail "wrote an output for $*"
  return 0
}
expect_failure 2 "--modulus-controls: expected 2..64" "$tmp/start.json" -o "$tmp/optimized.json" --modulus-controls 1
expect_failure 2 "--max-iterations" "$tmp/start.json" -o "$tmp/optimized.json" --max-iterations -5
expect_failure 2 '--scaling: expected log or linear, got "cubic"' "$tmp/start.json" -o "$tmp/optimized.json" --scaling cubic
expect_failure 2 '--start: expected design, uniform or uniform=MPa (a modulus > 0), got "uniform=-3"' "$tmp/start.json" -o "$tmp/optimized.json" --start uniform=-3
expect_failure 2 '--start: expected design' "$tmp/start.json" -o "$tmp/optimized.json" --start flat
expect_failure 2 '--start uniform=500: outside the bounds [8, 190] MPa (the floor and stiffest mix of' "$tmp/start.json" -o "$tmp/optimized.json" --start uniform=500
expect_failure 2 '--method: expected lbfgsb, mma or ccsaq, got "newton"' "$tmp/start.json" -o "$tmp/optimized.json" --method newton
expect_failure 2 "--threads: expected 0 (all cores) or a count from 1 to 256, got 999" "$tmp/start.json" -o "$tmp/optimized.json" --threads 999
expect_failure 1 "mechanics.load_cases: missing" "$tmp/graded.json" -o "$tmp/optimized.json"
expect_failure 1 "is also an input of this command" "$tmp/start.json" -o "$tmp/target.json"
expect_failure 1 "is also an input of this command" "$tmp/start.json" -o "$tmp/optimized.json" --plot "$tmp/optimized.json"
expect_failure 1 "convergence plot" "$tmp/start.json" -o "$tmp/optimized.json" --plot "$tmp/graded.json"
expect_failure 2 "--render and --plot: expected two different files" "$tmp/start.json" -o "$tmp/optimized.json" --plot "$tmp/a.png" --render "$tmp/a.png"
expect_failure 2 "--render: expected a value, got an empty string" "$tmp/start.json" -o "$tmp/optimized.json" --render ""
expect_failure 1 "is also an input of this command" "$tmp/start.json" -o "$tmp/optimized.json" --render "$tmp/target.json"
expect_failure 1 "shape render" "$tmp/start.json" -o "$tmp/optimized.json" --render "$tmp/graded.json"
python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
d = json.load(open(tmp + "/start.json"))
d["mechanics"]["load_cases"][0]["target"] = {"design": "missing.json"}
json.dump(d, open(tmp + "/missing-target.json", "w"))
c = d["mechanics"]["load_cases"][0]
c["target"] = {"design": "target.json"}
c["loads"][0]["force"], c["loads"][0]["moment"] = [0, 0, -4000.0], [0, 0, 5000.0]  # far past what the frame can carry
c["load_steps"], c["name"] = 1, "crush"
json.dump(d, open(tmp + "/crush.json", "w"))
c["loads"][0]["force"], c["loads"][0]["moment"] = [0, 0, -0.1], [0, 0, 0]
c["supports"][0]["type"], c["name"] = "pinned", "loose"  # free to turn about the pin: a mechanism
json.dump(d, open(tmp + "/loose.json", "w"))
d = json.load(open(tmp + "/start.json"))
d["optimize"]["bounds_mpa"] = [190, 8]
json.dump(d, open(tmp + "/bad-bounds.json", "w"))
d["optimize"]["bounds_mpa"] = [10, 100.00000001]
json.dump(d, open(tmp + "/narrow-bounds.json", "w"))
PY
# --start outside the design's own bounds: a usage error naming them to the last digit
expect_failure 2 "--start uniform=100.0000001: outside the bounds [10, 100.00000001] MPa ($tmp/narrow-bounds.json's optimize.bounds_mpa)" \
  "$tmp/narrow-bounds.json" -o "$tmp/optimized.json" --start uniform=100.0000001
expect_failure 1 "mechanics.load_cases[0].target.design: cannot read the target design" "$tmp/missing-target.json" -o "$tmp/optimized.json"
expect_failure 1 "optimize.bounds_mpa: expected the lowest modulus below the highest" "$tmp/bad-bounds.json" -o "$tmp/optimized.json"
expect_failure 1 'load case "crush" (mechanics.load_cases[0]) does not converge' "$tmp/crush.json" -o "$tmp/optimized.json"
expect_failure 1 'load case "loose" (mechanics.load_cases[0]): ' "$tmp/loose.json" -o "$tmp/optimized.json"
grep -q "mechanism" "$tmp/out" || fail "the mechanism is not explained: $(cat "$tmp/out")"
rm -f "$tmp/optimized.json"

# Outputs all or none, and what they replace kept until then: a --plot that cannot be written (in /proc)
# after the design was committed leaves the design the previous run wrote, byte for byte.
"$rodfab" optimize "$tmp/start.json" -o "$tmp/kept.json" --max-iterations 2 > "$tmp/out" 2>&1 || fail "a first run: $(cat "$tmp/out")"
cp "$tmp/kept.json" "$tmp/kept.before"
"$rodfab" optimize "$tmp/start.json" -o "$tmp/kept.json" --max-iterations 4 --plot /proc/rodfab-history.png > "$tmp/out" 2>&1 &&
  fail "a plot in /proc was written"
grep -qF "nothing was written" "$tmp/out" || fail "the failed plot: $(cat "$tmp/out")"
cmp -s "$tmp/kept.json" "$tmp/kept.before" || fail "a failed --plot lost the design the previous run wrote"
rm -f "$tmp/kept.json" "$tmp/kept.before"
# A plot of rodfab's edited past its mark (its first 128 bytes kept, the rest a person's) is theirs now.
python3 - "$tmp/history.png" "$tmp/edited.png" <<'PY'
import sys
data = open(sys.argv[1], "rb").read()
open(sys.argv[2], "wb").write(data[:128] + b"my annotated copy" + data[145:])
PY
"$rodfab" optimize "$tmp/start.json" -o "$tmp/kept.json" --max-iterations 2 --plot "$tmp/edited.png" > "$tmp/out" 2>&1 &&
  fail "an edited plot was replaced"
grep -qF "edited.png" "$tmp/out" || fail "the edited plot is not named: $(cat "$tmp/out")"
cmp -s <(python3 -c 'import sys; d=open(sys.argv[1],"rb").read(); sys.stdout.buffer.write(d[:128]+b"my annotated copy"+d[145:])' "$tmp/history.png") "$tmp/edited.png" ||
  fail "the edited plot changed"
rm -f "$tmp/edited.png" "$tmp/kept.json"

# SIGINT and SIGTERM: exit 130 / 143, nothing written. A chain of 20 rods with 16 controls each
# (320 design variables) and no tolerance runs for long enough to be interrupted mid-way.
python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
rods = [{"name": "link-%d" % i, "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[10 * i, 0, 0], [10 * i + 10, 0, 0]]},
         "section": {"shape": "circle", "diameter": 2.0}, "modulus": 100.0} for i in range(20)]
case = {"supports": [{"at": {"rod": "link-0", "end": "start"}, "type": "clamped"}],
        "loads": [{"at": {"rod": "link-19", "end": "end"}, "force": [0, 0.0005, 0.0005]}], "load_steps": 2}
json.dump({"format": "rodfab.design/1", "units": "mm", "rods": rods, "mechanics": case}, open(tmp + "/chain.json", "w"))
for r in rods: r["modulus"] = 60.0
json.dump({"format": "rodfab.design/1", "units": "mm", "rods": rods,
           "mechanics": dict(case, load_cases=[dict(case, name="hang", target={"design": "chain-target.json"})]),
           "optimize": {"modulus_controls": 16, "tolerance": 0, "max_iterations": 100000}}, open(tmp + "/chain-start.json", "w"))
PY
"$rodfab" simulate "$tmp/chain.json" -o "$tmp/chain-target.json" --no-estimate > "$tmp/out" 2>&1 || fail "simulate the chain: $(cat "$tmp/out")"
for sig in INT TERM; do
  rm -f "$tmp/out"  # else the loop below may read the last run's "iter 1" before this one truncates the file
  "$rodfab" optimize "$tmp/chain-start.json" -o "$tmp/optimized.json" --render "$tmp/chain.png" > "$tmp/out" 2>&1 &
  pid=$!
  for _ in $(seq 600); do grep -q "^iter    1 " "$tmp/out" && break; sleep 0.05; done
  grep -q "^iter    1 " "$tmp/out" || fail "SIG$sig: the chain did not start iterating: $(cat "$tmp/out")"
  kill -s $sig $pid
  wait $pid
  code=$?
  want=$([ $sig = INT ] && echo 130 || echo 143)
  [ "$code" -eq "$want" ] || fail "SIG$sig: exit $code, expected $want: $(cat "$tmp/out")"
  { [ -e "$tmp/optimized.json" ] || [ -e "$tmp/chain.png" ]; } && fail "SIG$sig left an output"
done
# A file a person saves at the output path while the optimizer runs is theirs: left as it is, exit 1.
rm -f "$tmp/out"
"$rodfab" optimize "$tmp/chain-start.json" -o "$tmp/raced.json" --max-iterations 60 > "$tmp/out" 2>&1 &
pid=$!
for _ in $(seq 600); do grep -q "^iter    1 " "$tmp/out" && break; sleep 0.05; done
echo '{"mine": true}' > "$tmp/raced.json"
wait $pid
code=$?
[ "$code" -eq 1 ] || fail "a file saved at the output meanwhile: exit $code, expected 1: $(cat "$tmp/out")"
grep -qF "was created while rodfab was working; it was left as it is" "$tmp/out" || fail "the race is not explained: $(cat "$tmp/out")"
[ "$(cat "$tmp/raced.json")" = '{"mine": true}' ] || fail "the file saved at the output was replaced"
rm -f "$tmp/raced.json"
# Many load cases, each keeping its own problem: the training's memory is estimated once the first
# case is built, and a budget below it is refused before the others are built or anything is solved.
python3 - "$tmp/many-cases.json" <<'PY'
import json, math, sys
n = 100
rods = [{"name": f"s{k}", "centerline": {"degree": 1, "knots": [0, 0, 1, 1],
         "points": [[0, 0, 0], [math.cos(2 * math.pi * k / n), math.sin(2 * math.pi * k / n), 0]]},
         "section": {"shape": "circle", "diameter": 0.05}, "modulus": 100.0} for k in range(n)]
supports = [{"at": {"rod": f"s{k}", "end": "end"}, "type": "clamped"} for k in range(n)]
target = {"rods": {"s0": {"centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0.001], [1, 0, 0]]}}}}
cases = [{"name": f"c{c}", "supports": supports, "loads": [{"at": {"point": [0, 0, 0]}, "force": [0, 0, 1e-6 * (c + 1)]}],
          "target": target} for c in range(64)]
json.dump({"format": "rodfab.design/1", "units": "mm", "rods": rods, "mechanics": {"poisson_ratio": 0.3, "load_cases": cases}},
          open(sys.argv[1], "w"))
PY
"$rodfab" optimize "$tmp/many-cases.json" -o "$tmp/optimized.json" --max-memory 256M > "$tmp/out" 2> "$tmp/err"
[ $? -eq 1 ] || fail "64 cases of a 100-rod star in 256 MiB: expected exit 1: $(cat "$tmp/out" "$tmp/err")"
grep -q "out of memory: optimizing $tmp/many-cases.json (64 load cases of 11200 unknowns) needs about [0-9.]* [MG]iB, more than the memory budget of 256 MiB (--max-memory); train on fewer load cases" "$tmp/err" ||
  fail "64 cases in 256 MiB: $(cat "$tmp/err")"
grep -q "^iter" "$tmp/out" && fail "64 cases in 256 MiB: iterated before refusing"
[ ! -e "$tmp/optimized.json" ] || fail "64 cases in 256 MiB: wrote an output"
ls -A "$tmp" | grep -q '^\.' && fail "temporaries left behind: $(ls -A "$tmp")"
echo "optimize: all checks passed"
