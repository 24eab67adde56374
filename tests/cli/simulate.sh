#!/usr/bin/env bash
# rodfab simulate from the command line: a cantilever rolled by an end moment lands where the
# elastica says, with an error estimate and a stability verdict; the output is a valid design that
# keeps its mechanics block; a strip past its buckling load is reported unstable; bad input is
# named and writes nothing; a star of many rods at one joint is held to its memory estimate.
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
grep -q "^step   4" "$tmp/out" && fail "more steps than asked for: $(cat "$tmp/out")"
grep -q "largest displacement" "$tmp/out" || fail "no summary: $(cat "$tmp/out")"
grep -q "^basis:     degree 6, 32 spans per rod (--spans); 266 unknowns" "$tmp/out" || fail "no basis line: $(cat "$tmp/out")"
grep -q "^accuracy:  estimated position error .* of the largest displacement (--accuracy 0.0001)" "$tmp/out" ||
  fail "no error estimate: $(cat "$tmp/out")"
# Three load steps: the verdict says |det J| was looked at too seldom to see every dip.
grep -q '^stability: stable as far as det J tells (det J was looked at after 3 load steps only: ' "$tmp/out" ||
  fail "no stability verdict with its caveat: $(cat "$tmp/out")"
grep -q "warning" "$tmp/out" && fail "unexpected warning: $(cat "$tmp/out")"
"$rodfab" validate "$tmp/rolled.json" > /dev/null 2>&1 || fail "the deformed design does not validate"
python3 - "$tmp/rolled.json" <<'PY' || fail "deformed design content"
import json, math, sys
d = json.load(open(sys.argv[1]))
rod = d["rods"][0]
tip = rod["centerline"]["points"][-1]  # clamped knots: the last control point is the tip
expect = 40 / math.pi
assert abs(tip[0] - expect) < 1e-3 and abs(tip[1] - expect) < 1e-3 and abs(tip[2]) < 1e-9, tip
assert rod["centerline"]["degree"] == 6 and len(rod["centerline"]["points"]) == 38
assert len(rod["orientation"]["quaternions"]) == 38
# The mechanics block stays, the load given by point now by rod end (the point has moved).
assert d["mechanics"]["loads"][0]["at"] == {"rod": "beam", "end": "end"}, d["mechanics"]
assert d["mechanics"]["supports"][0]["at"] == {"rod": "beam", "end": "start"}
PY
ls -A "$tmp" | grep -q tmp && fail "temporaries left behind: $(ls -A "$tmp")"

# The deformed design can be simulated again (here without loads: it stays where it is).
python3 - "$tmp/rolled.json" "$tmp/rolled-unloaded.json" <<'PY' || fail "edit the deformed design"
import json, sys
d = json.load(open(sys.argv[1]))
d["mechanics"]["loads"] = []
json.dump(d, open(sys.argv[2], "w"))
PY
"$rodfab" simulate "$tmp/rolled-unloaded.json" -o "$tmp/again.json" > "$tmp/out" 2>&1 || fail "simulate the deformed design: $(cat "$tmp/out")"
grep -q "largest displacement: 0 mm" "$tmp/out" || fail "the unloaded deformed design moved: $(cat "$tmp/out")"

# The deformed design can be voxelized like any other.
"$rodfab" voxelize "$tmp/rolled.json" --voxel-size 0.1,0.1,0.1 -o "$tmp/rolled.vdb" > /dev/null 2>&1 ||
  fail "voxelize the deformed design"

# JSON summary.
"$rodfab" simulate "$tmp/roll.json" --spans 16 -o "$tmp/rolled2.json" --json > "$tmp/json" || fail "--json"
python3 - "$tmp/json" <<'PY' || fail "--json content"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["rods"] == 1 and j["supports"] == 1 and j["unknowns"] == 7 * 22, j
assert j["discretization"] == {"degree": 6, "spans_per_rod": [16]}, j["discretization"]
assert len(j["load_steps"]) == 3 and j["load_steps"][-1]["load_factor"] == 1.0
assert all(s["residuals"][-1] < 1e-6 and s["cuts"] == 0 and s["det_sign"] == 1 for s in j["load_steps"])
assert abs(j["largest_displacement_mm"] - ((20 - 40 / 3.141592653589793) ** 2 + (40 / 3.141592653589793) ** 2) ** 0.5) < 1e-2
e = j["error_estimate"]
assert e["available"] and e["within_tolerance"] and e["position_error_mm"] < 1e-3 and e["tolerance"] == 1e-4, e
assert j["stability"] == "stable" and j["critical_points"] == []
assert j["stability_blind_spot"].startswith("det J was looked at after 3 load steps only"), j["stability_blind_spot"]
PY

# Ten load steps print ten steps; a step that Newton cannot take is cut, visibly.
edit() {  # OUT PYTHON-STATEMENTS (on d)
  python3 - "$tmp/roll.json" "$1" "$2" <<'PY'
import json, math, sys
d = json.load(open(sys.argv[1]))
exec(sys.argv[3])
json.dump(d, open(sys.argv[2], "w"))
PY
}
"$rodfab" simulate "$tmp/roll.json" --load-steps 10 -o "$tmp/ten.json" > "$tmp/out" 2>&1 || fail "10 steps: $(cat "$tmp/out")"
[ "$(grep -c "^step " "$tmp/out")" -eq 10 ] || fail "10 load steps did not print 10 steps: $(cat "$tmp/out")"
edit "$tmp/curl.json" 'd["mechanics"]["loads"][0]["moment"][2] *= 3.5; d["mechanics"]["load_steps"] = 1'
"$rodfab" simulate "$tmp/curl.json" --max-iterations 6 -o "$tmp/curl-out.json" > "$tmp/out" 2>&1 || fail "curl: $(cat "$tmp/out")"
grep -q "\[step cut [0-9]* time.*: +" "$tmp/out" || fail "step cuts not shown: $(cat "$tmp/out")"

# A strip past its lateral-torsional buckling load: unstable, said so; --follow-stable-branch buckles it.
python3 - "$tmp/strip.json" <<'PY'
import json, math, sys
E, nu, L, h, t = 1000.0, 0.3, 100.0, 10.0, 1.0
G = E / (2 * (1 + nu))
beta = 1 / 3 - 64 * t / (math.pi ** 5 * h) * sum(math.tanh(n * math.pi * h / (2 * t)) / n ** 5 for n in range(1, 100, 2))
EI, GJ = E * h * t ** 3 / 12, G * beta * h * t ** 3
P = 1.1 * 4.0126 * math.sqrt(EI * GJ) / L ** 2
design = {
  "format": "rodfab.design/1", "units": "mm",
  "rods": [{"name": "strip", "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [L, 0, 0]]},
            "normal": [0, 0, 1], "section": {"shape": "rectangle", "width": h, "height": t}, "modulus": E}],
  "mechanics": {"poisson_ratio": nu, "supports": [{"at": {"rod": "strip", "end": "start"}, "type": "clamped"}],
                "loads": [{"at": {"rod": "strip", "end": "end"}, "force": [0, 0, -P]}], "load_steps": 10}}
json.dump(design, open(sys.argv[1], "w"), indent=1)
PY
"$rodfab" simulate "$tmp/strip.json" -o "$tmp/strip-out.json" > "$tmp/out" 2> "$tmp/err" || fail "strip: $(cat "$tmp/out" "$tmp/err")"
grep -q "^stability: unstable; bifurcation between load factors 0.9" "$tmp/out" || fail "strip stability: $(cat "$tmp/out")"
grep -q "warning: the final state is an unstable equilibrium.*--follow-stable-branch" "$tmp/err" ||
  fail "no instability warning: $(cat "$tmp/err")"
"$rodfab" simulate "$tmp/strip.json" --follow-stable-branch -o "$tmp/strip-buckled.json" > "$tmp/out" 2> "$tmp/err" ||
  fail "strip, following: $(cat "$tmp/out" "$tmp/err")"
grep -q "^stability: stable; bifurcation between load factors .* (continued on the stable branch)" "$tmp/out" ||
  fail "strip branch switch: $(cat "$tmp/out")"
python3 - "$tmp/strip-buckled.json" <<'PY' || fail "the strip did not buckle sideways"
import json, sys
tip = json.load(open(sys.argv[1]))["rods"][0]["centerline"]["points"][-1]
assert abs(tip[1]) > 5, tip
PY

# A round column past its Euler load (pi^2 EI / 4 L^2): its two modes cross zero together, det J keeps
# its sign, and the verdict is still unstable, the crossing bracketed at 1 / 1.5 of the load.
edit "$tmp/column.json" 'd["mechanics"]["loads"] = [{"at": {"rod": "beam", "end": "end"}, "force": [-1.5 * math.pi ** 3 * 100 / 64 / 1600, 0, 0]}]; d["mechanics"]["load_steps"] = 5'
"$rodfab" simulate "$tmp/column.json" -o "$tmp/column-out.json" --json > "$tmp/json" 2> "$tmp/err" ||
  fail "round column: $(cat "$tmp/json" "$tmp/err")"
python3 - "$tmp/json" <<'PY' || fail "round column: $(cat "$tmp/json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["stability"] == "unstable" and len(j["critical_points"]) == 1, j
c = j["critical_points"][0]
# Shear lowers a column this stocky (L / d = 20) by about Pcr / (kappa G A) = 1.2e-3 of its load.
assert c["crossings"] == 2 and c["kind"] == "bifurcation" and c["to_load"] - c["from_load"] <= 1e-3, c
assert abs(0.5 * (c["from_load"] + c["to_load"]) - 1 / 1.5) < 1e-3, c
assert all(s["det_sign"] == 1 for s in j["load_steps"])
PY
"$rodfab" simulate "$tmp/column.json" -o "$tmp/column-out2.json" > "$tmp/out" 2> "$tmp/err" ||
  fail "round column: $(cat "$tmp/out" "$tmp/err")"
grep -q "^stability: unstable; bifurcation of two modes at once (det J kept its sign) between load factors 0.66" "$tmp/out" ||
  fail "round column verdict: $(cat "$tmp/out")"
grep -q "warning: the final state is an unstable equilibrium (two modes crossed zero together" "$tmp/err" ||
  fail "round column warning: $(cat "$tmp/err")"

# The same result for any thread count, byte for byte: a zigzag of 12 jointed rods (over a hundred
# collocation points, so TBB splits the assembly).
python3 - "$tmp/zigzag.json" <<'PY'
import json, sys
pts = [[10 * i, 4 * (i % 2), 0] for i in range(13)]
rods = [{"name": f"r{i}", "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [pts[i], pts[i + 1]]},
         "section": {"shape": "circle", "diameter": 1.0}, "modulus": 80.0} for i in range(12)]
design = {"format": "rodfab.design/1", "units": "mm", "rods": rods,
          "mechanics": {"supports": [{"at": {"rod": "r0", "end": "start"}, "type": "clamped"}],
                        "loads": [{"at": {"rod": "r11", "end": "end"}, "force": [0, -0.02, 0.01]}], "load_steps": 4}}
json.dump(design, open(sys.argv[1], "w"))
PY
"$rodfab" simulate "$tmp/zigzag.json" --threads 1 -o "$tmp/zigzag1.json" > /dev/null 2>&1 || fail "zigzag, 1 thread"
"$rodfab" simulate "$tmp/zigzag.json" --threads 2 -o "$tmp/zigzag2.json" > /dev/null 2>&1 || fail "zigzag, 2 threads"
cmp -s "$tmp/zigzag1.json" "$tmp/zigzag2.json" || fail "1 and 2 threads give different deformed designs"

# Errors: exit 1, the file and field named, nothing written.
expect_error() {  # NAME PATTERN DESIGN [OPTIONS...]
  local name=$1 pattern=$2 design=$3
  shift 3
  "$rodfab" simulate "$design" -o "$tmp/never.json" "$@" > /dev/null 2> "$tmp/err"
  [ $? -eq 1 ] || fail "$name: expected exit 1"
  grep -q -- "$pattern" "$tmp/err" || fail "$name: expected '$pattern' in: $(cat "$tmp/err")"
  [ ! -e "$tmp/never.json" ] || fail "$name: wrote an output"
}
edit "$tmp/nomech.json" 'del d["mechanics"]'
expect_error "no mechanics block" "nomech.json: mechanics: the design has no \"mechanics\" block" "$tmp/nomech.json"
edit "$tmp/nosupport.json" 'd["mechanics"]["supports"] = []'
expect_error "no support" "nosupport.json: mechanics.supports: no support" "$tmp/nosupport.json"
edit "$tmp/badrod.json" 'd["mechanics"]["loads"][0]["at"] = {"rod": "nope", "end": "end"}'
expect_error "unknown rod" "badrod.json: mechanics.loads\[0\].at.rod: no rod is named 'nope'" "$tmp/badrod.json"
edit "$tmp/badpoint.json" 'd["mechanics"]["loads"][0]["at"] = {"point": [10, 0.5, 0]}'
expect_error "load off the rods" "badpoint.json: mechanics.loads\[0\].at.point: no rod lies within joint_tolerance" "$tmp/badpoint.json"
edit "$tmp/badparameter.json" 'd["mechanics"]["loads"][0]["at"] = {"rod": "beam", "parameter": 1.5}'
expect_error "parameter off the rod" "badparameter.json: mechanics.loads\[0\].at.parameter: u = 1.5 lies outside rod \"beam\"'s centerline domain \[0, 1\]" \
  "$tmp/badparameter.json"
edit "$tmp/badnu.json" 'd["mechanics"]["poisson_ratio"] = 0.7'
expect_error "Poisson ratio" "badnu.json: mechanics.poisson_ratio: expected a Poisson ratio in" "$tmp/badnu.json"
edit "$tmp/pinned.json" 'd["mechanics"]["supports"][0]["type"] = "pinned"'
expect_error "a mechanism" "the structure is a mechanism" "$tmp/pinned.json"
expect_error "keeping degree 1" "rods\[0\].centerline.degree: the rod solver collocates second derivatives" "$tmp/roll.json" --degree 0
# The design's own basis of a one-span quadratic arc is refused, not solved coarsely.
edit "$tmp/arc.json" 'import math; w = math.cos(math.pi / 4); d["rods"][0]["centerline"] = {"degree": 2, "knots": [0, 0, 0, 1, 1, 1], "points": [[0, 0, 0], [20, 0, 0], [20, 20, 0]], "weights": [1, w, 1]}; d["mechanics"]["loads"][0]["at"] = {"rod": "beam", "end": "end"}'
expect_error "one-span arc on its own basis" "rods\[0\].centerline.degree: on its own degree-2 basis (--degree 0) this rod would need more than" "$tmp/arc.json" --degree 0
"$rodfab" simulate "$tmp/arc.json" -o "$tmp/arc-out.json" > /dev/null 2>&1 || fail "the arc rebuilt at the default degree"
# A kink of the modulus: rebuilt rods follow it with any --spans; on the design's own (quartic)
# basis --refine 2 puts a collocation point on it, refused naming --refine; automatic refinement avoids it.
edit "$tmp/kink.json" 'd["rods"][0]["modulus"] = {"degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [100, 40, 100]}; d["rods"][0]["centerline"] = {"degree": 4, "knots": [0, 0, 0, 0, 0, 1, 1, 1, 1, 1], "points": [[0, 0, 0], [5, 0, 0], [10, 0, 0], [15, 0, 0], [20, 0, 0]]}'
for spans in 9 10; do
  "$rodfab" simulate "$tmp/kink.json" --degree 5 --spans $spans -o "$tmp/kink-out.json" > /dev/null 2>&1 || fail "kinked modulus, --spans $spans"
done
expect_error "kinked modulus" "rods\[0\].modulus: E(s) has a kink at u = 0.5, which is a collocation point .* choose other --refine" "$tmp/kink.json" --degree 0 --refine 2
"$rodfab" simulate "$tmp/kink.json" --degree 0 -o "$tmp/kink-out.json" > /dev/null 2>&1 || fail "kinked modulus, automatic refinement"
"$rodfab" simulate "$tmp/roll.json" -o "$tmp/no/such/dir/x.json" 2> "$tmp/err"
[ $? -eq 1 ] || fail "missing output folder: expected exit 1"
grep -q "x.json: cannot write" "$tmp/err" || fail "missing output folder not named: $(cat "$tmp/err")"
# Only a design rodfab wrote, unchanged since (its "written_by" seal), is replaced: never one a person
# wrote (roll.json, in the same format) or edited (rolled.json with a rod renamed), --force or not.
cp "$tmp/roll.json" "$tmp/mine.json"
sed 's/"beam"/"my beam"/' "$tmp/rolled.json" > "$tmp/edited.json"
head -c 200 "$tmp/rolled.json" | grep -q '"written_by": "rodfab, xxh128 [0-9a-f]\{32\}"' || fail "rolled.json is not sealed"
for mine in mine edited; do
  cp "$tmp/$mine.json" "$tmp/$mine.before"
  "$rodfab" simulate "$tmp/roll.json" -o "$tmp/$mine.json" > /dev/null 2> "$tmp/err"
  [ $? -eq 1 ] || fail "$mine.json at the output: expected exit 1"
  grep -q "$mine.json: exists and is not a deformed design written by rodfab (or was changed since)" "$tmp/err" ||
    fail "$mine.json refusal: $(cat "$tmp/err")"
  cmp -s "$tmp/$mine.json" "$tmp/$mine.before" || fail "$mine.json was changed"
done
cp "$tmp/rolled.json" "$tmp/ours.json"
"$rodfab" simulate "$tmp/roll.json" -o "$tmp/ours.json" > /dev/null 2>&1 || fail "rodfab's own design not replaced"
"$rodfab" simulate "$tmp/roll.json" -o "$tmp/x.json" --degree 1 2> /dev/null
[ $? -eq 2 ] || fail "--degree 1: expected exit 2"
for bad in "--accuracy 0" "--accuracy 1e-300" "--accuracy 0.5" "--refine 2" "--degree 0 --spans 4" "--max-refinements -1" "--load-steps -3"; do
  "$rodfab" simulate "$tmp/roll.json" -o "$tmp/x.json" $bad 2> /dev/null
  [ $? -eq 2 ] || fail "$bad: expected exit 2"
done
"$rodfab" simulate "$tmp/roll.json" 2> /dev/null
[ $? -eq 2 ] || fail "no --output: expected exit 2"
"$rodfab" simulate --help | grep -q "usage: rodfab simulate" || fail "--help"

# Many rods at one joint (a star of N spokes clamped at a rim, loaded at the hub): the memory
# estimate (--json "memory") is checked before the solve against --max-memory. It bounds the heap the
# run adds to a tiny one's peak resident memory without being loose by more than 2 times; a budget
# below it is refused before anything is solved and writes nothing; a budget 2 % above it (also the
# process's data limit, so an estimate short of the real heap would end in out of memory) suffices.
star() {
  python3 - "$1" "$2" <<'PY'
import json, math, sys
n = int(sys.argv[1])
rods = [{"name": f"s{k}", "centerline": {"degree": 1, "knots": [0, 0, 1, 1],
         "points": [[0, 0, 0], [math.cos(2 * math.pi * k / n), math.sin(2 * math.pi * k / n), 0]]},
         "section": {"shape": "circle", "diameter": 0.05}, "modulus": 1000.0} for k in range(n)]
supports = [{"at": {"rod": f"s{k}", "end": "end"}, "type": "clamped"} for k in range(n)]
json.dump({"format": "rodfab.design/1", "units": "mm", "rods": rods,
           "mechanics": {"poisson_ratio": 0.3, "supports": supports, "load_steps": 1,
                         "loads": [{"at": {"point": [0, 0, 0]}, "force": [0, 0, 1e-7 * n]}]}}, open(sys.argv[2], "w"))
PY
}
# Peak resident memory (KiB) and the memory estimate (bytes) of a --json run: "KIB BYTES".
peak_and_estimate() {
  python3 - "$rodfab" "$@" <<'PY'
import json, resource, subprocess, sys
out = subprocess.run([sys.argv[1], "simulate"] + sys.argv[2:] + ["--json"], capture_output=True, text=True)
assert out.returncode == 0, out.stderr
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, json.loads(out.stdout)["memory"]["estimate_bytes"])
PY
}
star 400 "$tmp/star.json"
read -r base _ < <(peak_and_estimate "$tmp/roll.json" -o "$tmp/x.json") || fail "peak of the small run"
read -r peak estimate < <(peak_and_estimate "$tmp/star.json" -o "$tmp/x.json") || fail "peak of the star"
heap=$(( (peak - base) * 1024 ))
[ "$estimate" -ge "$heap" ] || fail "star of 400 rods: estimate $estimate bytes below the $heap bytes the run added"
[ "$estimate" -le $((2 * heap)) ] || fail "star of 400 rods: estimate $estimate bytes, more than twice the $heap bytes the run added"
rm -f "$tmp/x.json"
"$rodfab" simulate "$tmp/star.json" -o "$tmp/x.json" --max-memory 200M > "$tmp/out" 2> "$tmp/err"
[ $? -eq 1 ] || fail "star of 400 rods in 200 MiB: expected exit 1"
grep -q "out of memory: simulating $tmp/star.json (44800 unknowns) needs about [0-9.]* MiB, more than the memory budget of 200 MiB (--max-memory); use a coarser discretization" "$tmp/err" ||
  fail "star of 400 rods in 200 MiB: $(cat "$tmp/err")"
grep -q "^step" "$tmp/out" && fail "star of 400 rods in 200 MiB: solved before refusing"
[ ! -e "$tmp/x.json" ] || fail "star of 400 rods in 200 MiB: wrote an output"
"$rodfab" simulate "$tmp/star.json" -o "$tmp/x.json" --max-memory $((estimate + estimate / 50)) > /dev/null 2> "$tmp/err" ||
  fail "star of 400 rods within its estimate: $(cat "$tmp/err")"

# The bundled unfolding box's training case, as examples/README.md runs it: its hinges end on the
# squares' edges (T-joints); folded, the loads given by point are named by rod and parameter.
"$rodfab" simulate "$src/examples/unfolding-box.json" -o "$tmp/box.json" > "$tmp/out" 2>&1 || fail "unfolding box: $(cat "$tmp/out")"
grep -q "^structure: 44 joints, 4 supports$" "$tmp/out" || fail "unfolding box joints: $(grep -v '^step' "$tmp/out")"
grep -q "^converged: " "$tmp/out" || fail "unfolding box not converged: $(grep -v '^step' "$tmp/out")"
grep -q "warning" "$tmp/out" && fail "unfolding box: unexpected warning: $(grep -v '^step' "$tmp/out")"
python3 - "$tmp/box.json" <<'PY' || fail "folded box content"
import json, sys
d = json.load(open(sys.argv[1]))
at = d["mechanics"]["loads"][0]["at"]
assert at["rod"] == "square10-edge0" and abs(at["parameter"] - 0.5) < 1e-9, at
PY
# The same rod drawn as one cubic span and solved on its own basis at --refine 3 (16 spans after
# refining, where the a priori model asks 57 x 20 x 1.2 x 0.1 = 137 for 1 %): told, on stderr and in
# --json, whatever the estimate says.
python3 - "$tmp/roll.json" "$tmp/cubic.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
d["rods"][0]["centerline"] = {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "points": [[0, 0, 0], [20 / 3, 0, 0], [40 / 3, 0, 0], [20, 0, 0]]}
json.dump(d, open(sys.argv[2], "w"))
PY
"$rodfab" simulate "$tmp/cubic.json" --degree 0 --refine 3 -o "$tmp/cubic-out.json" > "$tmp/out" 2> "$tmp/err" ||
  fail "cubic on its own basis: $(cat "$tmp/err")"
grep -q '^warning: rods\[0\] "beam" has 16 spans of degree 3 where the a priori model asks about 137 for even 1 % accuracy' "$tmp/err" ||
  fail "no under-resolved warning: $(cat "$tmp/err")"
"$rodfab" simulate "$tmp/cubic.json" --degree 0 --refine 3 --json -o "$tmp/cubic-out.json" > "$tmp/out" 2> "$tmp/err" ||
  fail "cubic --json: $(cat "$tmp/err")"
python3 - "$tmp/out" <<'PY' || fail "under_resolved in --json: $(head -c 2000 "$tmp/out")"
import json, sys
u = json.load(open(sys.argv[1]))["under_resolved"]
assert u == {"rod": 'rods[0] "beam"', "degree": 3, "spans": 16, "spans_needed": 137, "relative_error": 0.01}, u
PY
"$rodfab" simulate "$tmp/roll.json" --json -o "$tmp/rolled.json" > "$tmp/out" 2> "$tmp/err" || fail "--json: $(cat "$tmp/err")"
python3 -c 'import json, sys; assert json.load(open(sys.argv[1]))["under_resolved"] is None' "$tmp/out" ||
  fail "the automatic spans reported under-resolved"

echo "simulate: OK"
