#!/usr/bin/env bash
# rodfab validate from the command line: exit codes and messages a technician sees.
#   validate.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

for f in "$src"/examples/*.json; do
  "$rodfab" validate "$f" > "$tmp/out" 2>&1 || fail "bundled $f does not validate: $(cat "$tmp/out")"
  grep -q "valid:         yes" "$tmp/out" || fail "no verdict for $f"
done

"$rodfab" validate --json "$src/examples/unfolding-box.json" > "$tmp/json" || fail "--json"
grep -q '"rods": 34' "$tmp/json" || fail "--json lacks the rod count"
# The frames' estimated error: a number below the tolerance (1e-10 rad) on the bundled spring.
"$rodfab" validate --json "$src/examples/buckling-spring.json" > "$tmp/json" || fail "--json spring"
python3 -c 'import json,sys; e=json.load(open(sys.argv[1]))["frame_error_rad"]; sys.exit(0 if 0 <= e <= 1.1e-10 else 1)' "$tmp/json" ||
  fail "--json frame_error_rad: $(grep frame "$tmp/json")"
"$rodfab" validate "$src/examples/buckling-spring.json" | grep -Eq "^frames: +rotation-minimizing ones within [0-9.]+e-[0-9]+ rad of exact" ||
  fail "no frames line"

# A file with two errors: both are named with their JSON path, exit code 1.
cat > "$tmp/bad.json" <<'JSON'
{ "format": "rodfab.design/1", "units": "mm",
  "rods": [ { "name": "a", "centerline": { "degree": 1, "knots": [0, 0, 1], "points": [[0,0,0],[1,0,0]] },
              "section": { "shape": "circle", "diameter": -2 }, "modulus": 10 } ] }
JSON
"$rodfab" validate "$tmp/bad.json" > "$tmp/out" 2> "$tmp/err"
code=$?
[ $code -eq 1 ] || fail "bad design: exit code $code, expected 1"
grep -q "bad.json: rods\[0\].centerline.knots: expected 4 knots" "$tmp/err" || fail "knot error not reported: $(cat "$tmp/err")"
grep -q "bad.json: rods\[0\].section.diameter: expected a diameter in mm > 0" "$tmp/err" || fail "diameter error not reported: $(cat "$tmp/err")"
[ ! -s "$tmp/out" ] || fail "a failed validation printed a summary"

# 150 bad rods: the first 100 listed, a line saying the list was cut, and a count that does not take
# that line for an error.
python3 - "$tmp/many.json" <<'PY'
import json, sys
rod = lambda n: {"name": "r%d" % n, "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, n, 0], [1, n, 0]]},
                 "section": {"shape": "circle", "diameter": -2}, "modulus": 10}
json.dump({"format": "rodfab.design/1", "units": "mm", "rods": [rod(n) for n in range(150)]}, open(sys.argv[1], "w"))
PY
"$rodfab" validate "$tmp/many.json" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] || fail "150 bad rods: expected exit 1"
[ "$(grep -c "section.diameter: expected a diameter" "$tmp/err")" -eq 100 ] || fail "150 bad rods: not 100 listed: $(head -3 "$tmp/err")"
grep -q "many.json: more issues follow; only the first 100 are listed" "$tmp/err" || fail "no cut line: $(tail -3 "$tmp/err")"
[ "$(tail -1 "$tmp/err")" = "$tmp/many.json: 100 errors shown, more were found; the design is not valid" ] ||
  fail "150 bad rods, the count: $(tail -1 "$tmp/err")"

# A mechanics block a solve would refuse: validate says so (the checks made before solving), exit 1.
python3 - "$tmp" <<'PY'
import json, sys
rod = {"name": "c", "centerline": {"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [20, 0, 0]]},
       "section": {"shape": "circle", "diameter": 1}, "modulus": 100}
end = lambda e: {"rod": "c", "end": e}
cases = {"far": {"supports": [{"at": end("start"), "type": "clamped"}], "loads": [{"at": {"point": [100, 100, 100]}, "force": [0, 1, 0]}]},
         "unsupported": {"supports": [], "loads": [{"at": end("end"), "force": [0, 1, 0]}]},
         "fine": {"supports": [{"at": end("start"), "type": "clamped"}], "loads": [{"at": end("end"), "force": [0, 1, 0]}]}}
# Load cases for optimize beside a top-level block simulate solves: both are checked.
cases["far_top"] = dict(cases["far"], load_cases=[dict(cases["fine"], name="ok", target={"rods": {"c": {"centerline": rod["centerline"], "normal": [0, 0, 1]}}})])
for name, m in cases.items():
    json.dump({"format": "rodfab.design/1", "units": "mm", "rods": [rod], "mechanics": m}, open("%s/%s.json" % (sys.argv[1], name), "w"))
PY
"$rodfab" validate "$tmp/far.json" > "$tmp/out" 2> "$tmp/err"
[ $? -eq 1 ] && grep -q "far.json: mechanics.loads\[0\].at.point: no rod lies within joint_tolerance" "$tmp/err" &&
  grep -q "the design is not valid" "$tmp/err" || fail "a load point near no rod: $(cat "$tmp/err")"
[ ! -s "$tmp/out" ] || fail "a design its solve would refuse printed a summary"
"$rodfab" validate "$tmp/far_top.json" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] && grep -q "far_top.json: mechanics.loads\[0\].at.point: no rod lies within" "$tmp/err" ||
  fail "a bad top-level load beside load cases: $(cat "$tmp/err")"
"$rodfab" validate "$tmp/unsupported.json" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] && grep -q "mechanics.supports: no support" "$tmp/err" || fail "no support: $(cat "$tmp/err")"
"$rodfab" validate "$tmp/fine.json" > /dev/null 2>&1 || fail "a cantilever with its support and load does not validate"

"$rodfab" validate "$tmp/missing.json" 2> "$tmp/err"
[ $? -eq 1 ] || fail "missing file: expected exit 1"
grep -q "missing.json: cannot open" "$tmp/err" || fail "missing file not named"

"$rodfab" validate 2> /dev/null
[ $? -eq 2 ] || fail "no design argument: expected usage exit 2"
"$rodfab" validate --bogus x.json 2> /dev/null
[ $? -eq 2 ] || fail "unknown option: expected usage exit 2"
"$rodfab" validate --help | grep -q "usage: rodfab validate" || fail "--help"
"$rodfab" frobnicate 2> /dev/null
[ $? -eq 2 ] || fail "unknown command: expected exit 2"
echo "validate CLI: all checks passed"
