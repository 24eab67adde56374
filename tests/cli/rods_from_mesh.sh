#!/usr/bin/env bash
# rodfab rods-from-mesh from the command line: an ellipsoid mesh becomes a valid design whose rods
# (decoded here by Python, not by rodfab) number 3F/2 with F nodes of degree 3; STL and OBJ give the
# same file; a tray overhang, rods thicker than long and rods bent tighter than their section are warned about; bad input and bad options are named and write nothing.
#   rods_from_mesh.sh RODFAB SOURCE_DIR MAKE_TEST_MESH
set -u
rodfab=$1 src=$2 make_mesh=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$make_mesh" ellipsoid 16 "$tmp/e.stl" > /dev/null || fail "make_test_mesh"
"$make_mesh" ellipsoid 16 "$tmp/e.obj" > /dev/null || fail "make_test_mesh"
"$rodfab" rods-from-mesh "$tmp/e.stl" --faces 100 --diameter 1.2 -o "$tmp/e.json" > "$tmp/out" 2>&1 || fail "rods-from-mesh: $(cat "$tmp/out")"
grep -q "^rods:       150 rods, 100 nodes, 1 connected part" "$tmp/out" || fail "summary: $(cat "$tmp/out")"
grep -q "warning" "$tmp/out" && fail "unexpected warning: $(cat "$tmp/out")"
"$rodfab" validate "$tmp/e.json" > /dev/null 2>&1 || fail "the design does not validate"
python3 - "$tmp/e.json" <<'PY' || fail "design content"
import json, sys, collections
d = json.load(open(sys.argv[1]))
assert d["format"] == "rodfab.design/1"
ends = collections.Counter()
for r in d["rods"]:
    c = r["centerline"]
    assert c["degree"] == 3 and r["section"] == {"shape": "circle", "diameter": 1.2}, r
    ends[tuple(c["points"][0])] += 1
    ends[tuple(c["points"][-1])] += 1
    # on the ellipsoid 30 x 20 x 15 within the mesh's sag and the tolerance
    for p in (c["points"][0], c["points"][-1]):
        f = (p[0] / 30) ** 2 + (p[1] / 20) ** 2 + (p[2] / 15) ** 2
        assert abs(f - 1) < 0.02, (p, f)
assert len(d["rods"]) == 150 and len(ends) == 100 and set(ends.values()) == {3}, (len(d["rods"]), len(ends))
PY
"$rodfab" rods-from-mesh "$tmp/e.obj" --faces 100 --diameter 1.2 -o "$tmp/e-obj.json" > /dev/null 2>&1 || fail "OBJ input"
python3 - "$tmp/e.json" "$tmp/e-obj.json" <<'PY' || fail "STL and OBJ designs differ"
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
assert a["rods"] == b["rods"]
PY

# The same bytes on 1 and 2 threads.
"$rodfab" rods-from-mesh "$tmp/e.stl" --faces 100 --diameter 1.2 -o "$tmp/e1.json" --threads 1 > /dev/null 2>&1 || fail "--threads 1"
"$rodfab" rods-from-mesh "$tmp/e.stl" --faces 100 --diameter 1.2 -o "$tmp/e2.json" --threads 2 > /dev/null 2>&1 || fail "--threads 2"
cmp -s "$tmp/e1.json" "$tmp/e2.json" || fail "1 and 2 threads give different designs"

# --json summary; an existing design is replaced only with --force.
"$rodfab" rods-from-mesh "$tmp/e.stl" --faces 100 --diameter 1.2 -o "$tmp/e.json" > "$tmp/out" 2>&1 && fail "replaced without --force"
grep -q -- "--force" "$tmp/out" || fail "no hint at --force: $(cat "$tmp/out")"
"$rodfab" rods-from-mesh "$tmp/e.stl" --faces 60 --diameter 1 --section ellipse --breadth 2 -o "$tmp/e.json" --force --json > "$tmp/j" 2>&1 ||
  fail "--json: $(cat "$tmp/j")"
python3 -c "import json,sys; j=json.load(open(sys.argv[1])); b=j['bends']; assert (j['rods']==90 and j['nodes']==60 and j['components']==1 and
  b['section_radius_mm']==1 and b['smallest_radius_mm']>1 and b['rods_tighter_than_section']==0), j" "$tmp/j" ||
  fail "json summary: $(cat "$tmp/j")"

# A mesh larger than the tray: written, with a warning naming the axis and the overhang.
"$make_mesh" ellipsoid 8 "$tmp/big.obj" 600 100 100 > /dev/null
"$rodfab" rods-from-mesh "$tmp/big.obj" --faces 50 --diameter 2 -o "$tmp/big.json" > "$tmp/out" 2>&1 || fail "big mesh: $(cat "$tmp/out")"
grep -q "^warning: the rods are 11[0-9][0-9].[0-9] mm long in x, [0-9.]* mm more than the tray of stratasys" "$tmp/out" || fail "no overhang warning: $(cat "$tmp/out")"

# A mesh a few mm across (as one drawn in cm would be) with 1.2 mm rods: written, with a warning that
# the rods are thicker than they are long (0.7 mm on average here), naming the model's size.
"$make_mesh" ellipsoid 16 "$tmp/small.obj" 3 2 1.5 > /dev/null
"$rodfab" rods-from-mesh "$tmp/small.obj" --faces 100 --diameter 1.2 -o "$tmp/small.json" > "$tmp/out" 2>&1 || fail "small mesh: $(cat "$tmp/out")"
grep -q "^warning: the rods are 1.2 mm thick but only 0.[0-9]* mm long on average: .* the model is 7.[0-9]* x 5.[0-9]* x 4.[0-9]* mm" "$tmp/out" ||
  fail "no warning of rods thicker than long: $(cat "$tmp/out")"
# ... and that some of them bend tighter than their 0.6 mm radius over the coarse mesh's folds.
grep -q "^warning: [0-9]* of the 150 rods bend tighter than their section's radius (down to a 0.[0-9]* mm radius of curvature)" "$tmp/out" ||
  fail "no warning of rods bent tighter than their section: $(cat "$tmp/out")"

# The bundled bunny (a real scan, closed): 200 faces -> 300 rods, 200 nodes, one part; the training
# script adds a mechanics block that validates.
"$rodfab" rods-from-mesh "$src/examples/bunny.obj" --faces 200 --diameter 1.5 -o "$tmp/bunny.json" > "$tmp/out" 2>&1 ||
  fail "bunny: $(cat "$tmp/out")"
grep -q "^rods:       300 rods, 200 nodes, 1 connected part" "$tmp/out" || fail "bunny summary: $(cat "$tmp/out")"
python3 "$src/examples/bunny_ears_forward.py" "$tmp/bunny.json" "$tmp/bunny-train.json" > /dev/null || fail "bunny_ears_forward.py"
"$rodfab" validate "$tmp/bunny-train.json" > /dev/null 2>&1 || fail "the bunny training design does not validate"

# Bad input: named, exit 1, nothing written.
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n' > "$tmp/fin.obj"
"$rodfab" rods-from-mesh "$tmp/fin.obj" --faces 4 --diameter 1 -o "$tmp/fin.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] || fail "non-manifold mesh: exit $rc"
grep -q "fin.obj: non-manifold mesh: the edge from (0, 0, 0) to (1, 0, 0)" "$tmp/out" || fail "non-manifold message: $(cat "$tmp/out")"
grep -q "nothing was written" "$tmp/out" || fail "no 'nothing was written': $(cat "$tmp/out")"
[ -e "$tmp/fin.json" ] && fail "wrote a design for a bad mesh"
: > "$tmp/empty.stl"
"$rodfab" rods-from-mesh "$tmp/empty.stl" --faces 10 --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "empty.stl: the file is empty: it holds no faces" "$tmp/out" || fail "empty file: exit $rc: $(cat "$tmp/out")"
"$rodfab" rods-from-mesh "$tmp/e.stl" --faces 6000 --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "5120 triangles, fewer than the 6000 asked for" "$tmp/out" || fail "too many faces: exit $rc: $(cat "$tmp/out")"
"$rodfab" rods-from-mesh "$tmp/e.stl" -o "$tmp/e.stl" --faces 10 --diameter 1 --force > "$tmp/out" 2>&1 && fail "overwrote its input"
for bad in "--faces 3" "--faces 100001" "--faces x" "--diameter 0" "--diameter nan" "--subdivisions 1" "--section hexagon" \
           "--breadth 2" "--caps square" "--modulus -1" "--surface-tolerance 0" "--threads -1"; do
  # shellcheck disable=SC2086
  "$rodfab" rods-from-mesh "$tmp/e.stl" --diameter 1 -o "$tmp/x.json" $bad > "$tmp/out" 2>&1; rc=$?
  [ $rc -eq 2 ] || fail "$bad: exit $rc: $(cat "$tmp/out")"
done
[ -e "$tmp/x.json" ] && fail "wrote on a usage error"
echo "rods_from_mesh: ok"
