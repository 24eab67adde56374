#!/usr/bin/env bash
# rodfab voxelize from the command line: a bundled design to a .vdb OpenVDB's own tools read, and the
# errors a technician sees.
#   voxelize.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$rodfab" voxelize "$src/examples/unfolding-box.json" --voxel-size 0.1,0.1,0.1 -o "$tmp/box.vdb" > "$tmp/out" 2>&1 ||
  fail "voxelize the unfolding box: $(cat "$tmp/out")"
grep -q "active voxels:" "$tmp/out" || fail "no statistics printed: $(cat "$tmp/out")"
[ -s "$tmp/box.vdb" ] || fail "no grid written"
[ "$(ls -A "$tmp")" = "box.vdb
out" ] || fail "temporaries left beside the grid: $(ls -A "$tmp")"

# OpenVDB's own tool reads the file: the grid name, its float type and the active voxel count agree.
if command -v vdb_print > /dev/null; then
  vdb_print -l "$tmp/box.vdb" > "$tmp/vdb" 2>&1 || fail "vdb_print cannot read the grid: $(cat "$tmp/vdb")"
  grep -q "Name: modulus_mpa" "$tmp/vdb" || fail "grid name: $(cat "$tmp/vdb")"
  grep -q "Tree_float" "$tmp/vdb" || fail "grid type: $(cat "$tmp/vdb")"
  active=$(sed -n 's/^active voxels: *\([0-9]*\).*/\1/p' "$tmp/out")
  vdbactive=$(sed -n 's/.*Number of active voxels: *\([0-9,]*\).*/\1/p' "$tmp/vdb" | tr -d ,)
  [ "$active" = "$vdbactive" ] || fail "active voxels: rodfab says $active, vdb_print $vdbactive"
fi

# The same bytes on 1 thread as on all cores (OpenVDB alone writes a random UUID into every file).
"$rodfab" voxelize "$src/examples/unfolding-box.json" --voxel-size 0.1,0.1,0.1 --threads 1 -o "$tmp/one.vdb" > /dev/null 2>&1 ||
  fail "voxelize on 1 thread"
cmp -s "$tmp/box.vdb" "$tmp/one.vdb" || fail "the grid files of 1 thread and all cores differ"
rm -f "$tmp/one.vdb"

# JSON: per-rod counts add up to the active voxels, the voxel size is the one asked for.
"$rodfab" voxelize "$src/examples/unfolding-box.json" --voxel-size 0.1,0.1,0.1 -o "$tmp/box.vdb" --json > "$tmp/json" ||
  fail "--json"
python3 - "$tmp/json" <<'PY' || fail "--json content"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["voxel_size_mm"] == [0.1, 0.1, 0.1], j["voxel_size_mm"]
assert len(j["rods"]) == 34
assert sum(r["voxels"] for r in j["rods"]) == j["active_voxels"] > 0
assert abs(j["occupied_volume_mm3"] - j["active_voxels"] * 1e-3) < 1e-6 * j["occupied_volume_mm3"]
assert j["modulus_mpa"]["min"] <= j["modulus_mpa"]["mean"] <= j["modulus_mpa"]["max"]
PY

# Bad input: usage errors exit 2, bad files exit 1, and nothing is written.
for size in 0.1,0.1 0.1,0,0.1 a,b,c 0.1,0.1,0.1,0.1 -1,0.1,0.1; do
  "$rodfab" voxelize "$src/examples/unfolding-box.json" --voxel-size "$size" -o "$tmp/x.vdb" 2> "$tmp/err"
  [ $? -eq 2 ] || fail "--voxel-size $size: expected exit 2"
  grep -q -- "--voxel-size: expected three sizes from" "$tmp/err" || fail "--voxel-size $size: $(cat "$tmp/err")"
done
"$rodfab" voxelize "$src/examples/unfolding-box.json" 2> /dev/null
[ $? -eq 2 ] || fail "no --output: expected exit 2"
"$rodfab" voxelize "$tmp/missing.json" -o "$tmp/x.vdb" 2> "$tmp/err"
[ $? -eq 1 ] || fail "missing design: expected exit 1"
grep -q "missing.json: cannot open" "$tmp/err" || fail "missing design not named: $(cat "$tmp/err")"
echo '{ "format": "rodfab.design/1", "units": "mm", "rods": [ { "name": "a" } ] }' > "$tmp/bad.json"
"$rodfab" voxelize "$tmp/bad.json" -o "$tmp/x.vdb" 2> "$tmp/err"
[ $? -eq 1 ] || fail "bad design: expected exit 1"
grep -q "bad.json: rods\[0\]" "$tmp/err" || fail "bad design errors not named: $(cat "$tmp/err")"
"$rodfab" voxelize "$src/examples/unfolding-box.json" --voxel-size 0.2,0.2,0.2 -o "$tmp/no/such/dir/x.vdb" 2> "$tmp/err"
[ $? -eq 1 ] || fail "unwritable output: expected exit 1"
grep -q "x.vdb: cannot write" "$tmp/err" || fail "unwritable output not named: $(cat "$tmp/err")"
[ ! -e "$tmp/x.vdb" ] || fail "a failed run left a grid behind"
"$rodfab" voxelize --help | grep -q "usage: rodfab voxelize" || fail "--help"

# Hostile designs from the reliability report: kinks, folds, extreme weights, sections thicker than
# their bend or 500:1 flat, a rod far from the origin. Each must voxelize and slice within 4 GB of
# address space and a minute, and the job must pass its own inspection (no voxel outside the part).
design() {  # NAME DEGREE KNOTS POINTS [WEIGHTS] SECTION [EXTRA]
  local weights=""
  [ -n "$5" ] && weights=", \"weights\": $5"
  cat > "$tmp/$1.json" <<JSON
{ "format": "rodfab.design/1", "units": "mm", "rods": [ { "name": "$1",
  "centerline": { "degree": $2, "knots": $3, "points": $4$weights },
  "section": $6, "modulus": { "degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [8, 120, 40] }${7:-} } ] }
JSON
}
s_bend='[[0,0,0],[1,0,0],[2,1,0],[3,1,0]]' cubic='[0,0,0,0,1,1,1,1]'
design readme-d4 3 "$cubic" "$s_bend" "" '{"shape": "circle", "diameter": 4}'
design weights 3 "$cubic" "$s_bend" '[1, 1e3, 1e3, 1]' '{"shape": "circle", "diameter": 1.5}'
design cusp 3 "$cubic" '[[0,0,0],[2,2,0],[0,2,0],[2,0,0]]' "" '{"shape": "circle", "diameter": 1.5}'
design flat-ellipse 3 "$cubic" "$s_bend" "" '{"shape": "ellipse", "width": 5, "height": 0.01}' ', "normal": [0, 0, 1]'
design far 3 "$cubic" '[[1e8,1e8,0],[100000001,1e8,0],[100000002,100000001,0],[100000003,100000001,0]]' "" '{"shape": "circle", "diameter": 1.5}'
design kink-xy 1 '[0,0,0.5,1,1]' '[[0,0,0],[3,0,0],[5,2,0]]' "" '{"shape": "circle", "diameter": 1}'
design kink-xz 1 '[0,0,0.5,1,1]' '[[0,0,0],[3,0,0],[5,0,2]]' "" '{"shape": "rectangle", "width": 1, "height": 0.6}' ', "normal": [0, 1, 0], "caps": "flat"'
design double-knot 2 '[0,0,0,0.5,0.5,1,1,1]' '[[0,0,0],[1,0,0],[2,0,0],[2,1,0],[2,2,0]]' "" '{"shape": "circle", "diameter": 1}'
for name in readme-d4 weights cusp flat-ellipse far kink-xy kink-xz double-knot; do
  prlimit --as=4000000000 timeout 60 "$rodfab" voxelize "$tmp/$name.json" -o "$tmp/$name.vdb" > "$tmp/out" 2>&1 ||
    fail "voxelize $name (exit $?): $(tail -3 "$tmp/out")"
  grep -q "active voxels:" "$tmp/out" || fail "voxelize $name: $(cat "$tmp/out")"
  prlimit --as=4000000000 timeout 60 "$rodfab" slice "$tmp/$name.json" -o "$tmp/$name.zip" --quiet > "$tmp/out" 2>&1 ||
    fail "slice $name (exit $?): $(tail -3 "$tmp/out")"
  "$rodfab" inspect "$tmp/$name.zip" > "$tmp/out" 2>&1 || fail "inspect $name: $(tail -5 "$tmp/out")"
  rm -f "$tmp/$name.vdb" "$tmp/$name.zip"
done
# Out of range: a clear message, not "length is zero".
design huge 1 '[0,0,1,1]' '[[0,0,0],[1e300,0,0]]' "" '{"shape": "circle", "diameter": 1}'
"$rodfab" voxelize "$tmp/huge.json" -o "$tmp/x.vdb" 2> "$tmp/err"
[ $? -eq 1 ] || fail "huge coordinates: expected exit 1"
grep -q "huge.json: rods\[0\].centerline.points\[1\]: expected coordinates within +-1e9 mm" "$tmp/err" ||
  fail "huge coordinates: $(cat "$tmp/err")"
echo "voxelize: ok"
