#!/usr/bin/env bash
# rodfab rods-from-cad from the command line: a box's STEP model (written by OpenCASCADE) becomes 12
# straight rods meeting 3 by 3 at the corners (decoded here by Python); a circle in IGES becomes one
# rational rod on the circle; bad input is named, exits 1 and writes nothing.
#   rods_from_cad.sh RODFAB SOURCE_DIR MAKE_TEST_CAD
set -u
rodfab=$1 src=$2 make_cad=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$make_cad" box "$tmp/box.step" > /dev/null 2>&1 || fail "make_test_cad box"
"$rodfab" rods-from-cad "$tmp/box.step" --diameter 1 -o "$tmp/box.json" > "$tmp/out" 2>&1 || fail "rods-from-cad: $(cat "$tmp/out")"
grep -q "^rods:       12 rods, 8 joints" "$tmp/out" || fail "summary: $(cat "$tmp/out")"
"$rodfab" validate "$tmp/box.json" > /dev/null 2>&1 || fail "the design does not validate"
python3 - "$tmp/box.json" <<'PY' || fail "box design content"
import json, sys, collections
d = json.load(open(sys.argv[1]))
ends = collections.Counter()
for r in d["rods"]:
    pts = r["centerline"]["points"]
    a, b = pts[0], pts[-1]
    ends[tuple(a)] += 1; ends[tuple(b)] += 1
    assert all(abs(c) < 1e-9 or abs(c - m) < 1e-9 for p in (a, b) for c, m in zip(p, (10, 20, 30))), (a, b)
    assert sum(abs(x - y) > 1e-9 for x, y in zip(a, b)) == 1, (a, b)   # along one axis
assert len(ends) == 8 and set(ends.values()) == {3}, ends
PY
# A tolerance above the box's 30 mm edges chains all 24 ends into one joint 37 mm across (its
# diagonal): refused (exit 1, nothing written), not collapsed onto one point.
"$rodfab" rods-from-cad "$tmp/box.step" --diameter 1 --joint-tolerance 35 -o "$tmp/lump.json" > "$tmp/out" 2>&1 &&
  fail "a joint wider than the tolerance was accepted: $(cat "$tmp/out")"
[ $? -eq 1 ] || fail "a joint wider than the tolerance: exit code"
grep -q "24 curve ends chain into one joint 37.4 mm across" "$tmp/out" || fail "wide joint message: $(cat "$tmp/out")"
[ ! -e "$tmp/lump.json" ] || fail "a joint wider than the tolerance wrote a design"

"$make_cad" circle "$tmp/circle.iges" > /dev/null 2>&1 || fail "make_test_cad circle"
"$rodfab" rods-from-cad "$tmp/circle.iges" --diameter 0.8 --section ellipse --breadth 1.2 -o "$tmp/circle.json" --json > "$tmp/j" 2>&1 ||
  fail "circle: $(cat "$tmp/j")"
python3 - "$tmp/circle.json" <<'PY' || fail "circle design content"
import json, sys, math
d = json.load(open(sys.argv[1]))
assert len(d["rods"]) == 1
c = d["rods"][0]["centerline"]
assert "weights" in c and c["points"][0] == c["points"][-1], c
# every rational control point's projection stays near the circle (centre (3,-2,7), radius 5): the
# first point is on it exactly.
p = c["points"][0]
assert abs(math.dist(p, (3, -2, 7)) - 5) < 1e-9, p
assert d["rods"][0]["section"]["shape"] == "ellipse" and "normal" in d["rods"][0]
PY
python3 -c "import json,sys; b=json.load(open(sys.argv[1]))['bends']; assert (abs(b['smallest_radius_mm']-5)<1e-6 and
  b['section_radius_mm']==0.6 and b['rods_tighter_than_section']==0), b" "$tmp/j" || fail "circle bends: $(cat "$tmp/j")"
# A rod 12 mm thick on that 5 mm circle folds over itself: written, with a warning.
"$rodfab" rods-from-cad "$tmp/circle.iges" --diameter 12 -o "$tmp/circle.json" --force > "$tmp/out" 2>&1 || fail "thick circle: $(cat "$tmp/out")"
grep -q "^warning: 1 of the 1 rods bend tighter than their section's radius (down to a 5 mm radius of curvature)" "$tmp/out" ||
  fail "no warning of a rod bent tighter than its section: $(cat "$tmp/out")"

# An offset curve (OpenCASCADE's exact B-spline of it is of degree 14): approximated, said in the summary
# and the JSON, and the design validates.
sed "s/^#15 = GEOMETRIC_CURVE_SET(.*/#15 = GEOMETRIC_CURVE_SET('',(#108));/" "$src/tests/fuzz/seeds/cad/wireframe.step" > "$tmp/offset.step"
grep -q "^#108 = OFFSET_CURVE_3D" "$tmp/offset.step" || fail "the wireframe seed has no offset curve #108"
"$rodfab" rods-from-cad "$tmp/offset.step" --diameter 1 -o "$tmp/offset.json" > "$tmp/out" 2>&1 || fail "offset curve: $(cat "$tmp/out")"
grep -q "^curves:     1 of a degree above 7 approximated by degree 7 within 1e-05 mm" "$tmp/out" || fail "offset summary: $(cat "$tmp/out")"
"$rodfab" validate "$tmp/offset.json" > /dev/null 2>&1 || fail "the offset curve's design does not validate"
"$rodfab" rods-from-cad "$tmp/offset.step" --diameter 1 -o "$tmp/offset.json" --force --json > "$tmp/j" 2>&1 || fail "offset --json: $(cat "$tmp/j")"
python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); assert r["approximated"] == 1 and 0 < r["largest_approximation_error_mm"] <= 1e-5, r' "$tmp/j" ||
  fail "offset JSON: $(cat "$tmp/j")"

# A curve set OpenCASCADE cannot convert (an offset of a curve whose end derivatives vanish): the other
# set's rod written, the dropped set named in a warning and in the JSON.
"$rodfab" rods-from-cad "$src/tests/fuzz/seeds/cad/untranslated.step" --diameter 1 -o "$tmp/part.json" > "$tmp/out" 2> "$tmp/err" ||
  fail "untranslated: $(cat "$tmp/out" "$tmp/err")"
grep -q "^warning: OpenCASCADE could not convert 1 entity of the model, wholly or in part, and the design lacks what it could not: entity #15 (" "$tmp/err" ||
  fail "untranslated warning: $(cat "$tmp/err")"
grep -q "^rods:       1 rods" "$tmp/out" || fail "untranslated summary: $(cat "$tmp/out")"
"$rodfab" rods-from-cad "$src/tests/fuzz/seeds/cad/untranslated.step" --diameter 1 -o "$tmp/part.json" --force --json > "$tmp/j" 2> /dev/null ||
  fail "untranslated --json"
python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); assert r["untranslated"] == 1 and r["first_untranslated"].startswith("entity #15 ("), r' "$tmp/j" ||
  fail "untranslated JSON: $(cat "$tmp/j")"

# Bad input: exit 1, the file named, nothing written.
echo "not a step file" > "$tmp/junk.step"
"$rodfab" rods-from-cad "$tmp/junk.step" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "junk.step: not a readable STEP file" "$tmp/out" || fail "junk: exit $rc: $(cat "$tmp/out")"
"$rodfab" rods-from-cad "$tmp/nothing.igs" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "nothing.igs: no such file" "$tmp/out" || fail "missing: exit $rc: $(cat "$tmp/out")"
"$rodfab" rods-from-cad "$tmp/box.step" --diameter 1 -o "$tmp/box.json" > "$tmp/out" 2>&1 && fail "replaced without --force"
for bad in "--diameter 0" "--joint-tolerance 0" "--section star" "--modulus 0"; do
  # shellcheck disable=SC2086
  "$rodfab" rods-from-cad "$tmp/box.step" -o "$tmp/x.json" --diameter 1 $bad > "$tmp/out" 2>&1; rc=$?
  [ $rc -eq 2 ] || fail "$bad: exit $rc: $(cat "$tmp/out")"
done
# Hostile input: an entity id OpenCASCADE's parser would overflow on; a box moved beyond +-1e9 mm,
# which validate would refuse (tests/test_meshing_cad.cpp has the other cases).
printf "ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#99999999999999999999=CARTESIAN_POINT('',(0.,0.,0.));\nENDSEC;\nEND-ISO-10303-21;\n" > "$tmp/id.step"
"$rodfab" rods-from-cad "$tmp/id.step" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "id.step: line 5: an entity id above 999999999" "$tmp/out" || fail "huge id: exit $rc: $(cat "$tmp/out")"
sed 's/(0\.,0\.,0\.)/(1.E12,0.,0.)/g' "$tmp/box.step" > "$tmp/far.step"
"$rodfab" rods-from-cad "$tmp/far.step" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "far.step: edge 0: a control point at (2e+12, 0, 0) mm, beyond the +-1e9 mm" "$tmp/out" ||
  fail "far box: exit $rc: $(cat "$tmp/out")"
[ -e "$tmp/x.json" ] && fail "wrote after an error"
# A truncated IGES file (OpenCASCADE's reader crashes on it) is refused as cut short: exit 1, the file
# named, nothing written.
"$make_cad" spline "$tmp/spline.iges" > /dev/null 2>&1 || fail "make_test_cad spline"
head -c 700 "$tmp/spline.iges" > "$tmp/cut.iges"
"$rodfab" rods-from-cad "$tmp/cut.iges" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "^$tmp/cut.iges: the file ends without IGES's Terminate record" "$tmp/out" || fail "truncated IGES: exit $rc: $(cat "$tmp/out")"
[ -e "$tmp/x.json" ] && fail "wrote after a truncated file"
# Files that crashed OpenCASCADE's reader (found by mutating the seed models; tests/data/cad-crashers):
# exit 1, the file named, nothing written, whether or not a later OpenCASCADE still crashes on them.
for model in "$src"/tests/data/cad-crashers/*; do
  "$rodfab" rods-from-cad "$model" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1; rc=$?
  [ $rc -eq 1 ] && grep -q "^$model: " "$tmp/out" || fail "$(basename "$model"): exit $rc: $(cat "$tmp/out")"
  [ -e "$tmp/x.json" ] && fail "wrote from $(basename "$model")"
done
# One of them is now named before the transfer (cad_checks.cpp, pointProblem).
"$rodfab" rods-from-cad "$src/tests/data/cad-crashers/box-2d-vertex-point.step" --diameter 1 -o "$tmp/x.json" > "$tmp/out" 2>&1
grep -q "box-2d-vertex-point.step: malformed: entity #22 (VERTEX_POINT): a vertex whose point is not 3D" "$tmp/out" ||
  fail "2D vertex point: $(cat "$tmp/out")"
# SIGTERM while OpenCASCADE reads a large model (10 curve sets of 20,000 lines, ~7 s to read): exit 143
# without waiting for the read (within 3 s even on a loaded machine; ~0.02 s here), the reader process
# gone, nothing written.
# $1: the file, $2 curve sets of $3 lines each.
write_lines_step() {
python3 - "$@" <<'PY'
import sys
out = ["ISO-10303-21;", "HEADER;", "FILE_DESCRIPTION(('x'),'2;1');", "FILE_NAME('x','',(''),(''),'','','');",
       "FILE_SCHEMA(('CONFIG_CONTROL_DESIGN'));", "ENDSEC;", "DATA;"]
n = 1
for s in range(int(sys.argv[2])):
    items = []
    for i in range(int(sys.argv[3])):
        out += [f"#{n}=CARTESIAN_POINT('',({i}.,{s}.,0.));", f"#{n+1}=DIRECTION('',(1.,0.,0.));",
                f"#{n+2}=VECTOR('',#{n+1},1.);", f"#{n+3}=LINE('',#{n},#{n+2});"]
        items.append(n + 3)
        n += 4
    out.append(f"#{n}=GEOMETRIC_CURVE_SET('',(" + ",".join(f"#{x}" for x in items) + "));")
    n += 1
out += ["ENDSEC;", "END-ISO-10303-21;"]
open(sys.argv[1], "w").write("\n".join(out) + "\n")
PY
}
# A file whose reading needs more than the budget at the least rate measured (8 bytes a byte when the
# design is written, not kept: 9.6 MB of lines, 77 MB) is refused before the reader starts, naming the
# file and the figures.
write_lines_step "$tmp/lines.step" 8 10000
"$rodfab" rods-from-cad "$tmp/lines.step" --diameter 1 -o "$tmp/x.json" --max-memory 64M > "$tmp/out" 2>&1
rc=$?
[ $rc -eq 1 ] && grep -q "out of memory: reading the CAD model $tmp/lines.step needs about" "$tmp/out" && grep -q "split the model" "$tmp/out" ||
  fail "CAD model over the budget: exit $rc: $(cat "$tmp/out")"
[ -e "$tmp/x.json" ] && fail "wrote a design over the budget"
write_lines_step "$tmp/large.step" 10 20000
"$rodfab" rods-from-cad "$tmp/large.step" --diameter 1 -o "$tmp/x.json" --max-memory 8G > "$tmp/out" 2>&1 &
pid=$!
# The child of $1, from /proc (no procps on a minimal machine).
child_of() {
  local stat cpid comm state ppid
  for stat in /proc/[0-9]*/stat; do
    read -r cpid comm state ppid _ < "$stat" 2> /dev/null && [ "$ppid" = "$1" ] && echo "$cpid"
  done
  return 0
}
reader=
for _ in $(seq 50); do reader=$(child_of $pid); [ -n "$reader" ] && break; sleep 0.1; done
[ -n "$reader" ] && grep -aq rodfab-cad-reader "/proc/$reader/cmdline" || fail "no CAD reader process under rods-from-cad"
sleep 0.5
start=$(date +%s%N)
kill -TERM $pid
wait $pid; rc=$?
elapsed_ms=$(( ($(date +%s%N) - start) / 1000000 ))
[ $rc -eq 143 ] || fail "SIGTERM during the CAD reader: exit $rc: $(cat "$tmp/out")"
[ $elapsed_ms -le 3000 ] || fail "SIGTERM took $elapsed_ms ms"
sleep 0.2
kill -0 "$reader" 2> /dev/null && fail "the CAD reader $reader outlived rods-from-cad"
[ -e "$tmp/x.json" ] && fail "wrote after SIGTERM"
echo "rods_from_cad: ok"
