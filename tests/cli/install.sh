#!/usr/bin/env bash
# Installed and relocated: `cmake --install` into a temporary prefix, the tree moved elsewhere, an
# example sliced from a third folder; nothing of the build machine's paths in the installed files or in
# the job; a clear error when the data folder is missing or RODFAB_DATA_DIR is wrong; with MAKE_TEST_CAD,
# rods-from-cad through the installed CAD reader process, and a clear error (the rest working) without it.
#   install.sh CMAKE BUILD_DIR SOURCE_DIR [MAKE_TEST_CAD]
set -u
cmake=$1 build=$(cd "$2" && pwd -P) src=$(cd "$3" && pwd -P) make_cad=${4:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
unset RODFAB_DATA_DIR

"$cmake" --install "$build" --prefix "$tmp/prefix" > "$tmp/log" 2>&1 || fail "cmake --install: $(tail -5 "$tmp/log")"
[ -x "$tmp/prefix/bin/rodfab" ] || fail "no bin/rodfab"
for entry in profiles calibration/default-60C.json masks examples/unfolding-box.json; do
  [ -e "$tmp/prefix/share/rodfab/$entry" ] || fail "share/rodfab/$entry was not installed"
done
for profile in "$src"/printer_profiles/*.json; do  # every bundled profile, whatever its name
  [ -f "$tmp/prefix/share/rodfab/profiles/$(basename "$profile")" ] || fail "profile $(basename "$profile") not installed"
done
echo "installed: $(du -sk "$tmp/prefix" | cut -f1) kB in $(find "$tmp/prefix" -type f | wc -l) files"

# Moved: nothing may point back to the prefix, the build or the sources.
mv "$tmp/prefix" "$tmp/moved"
installed=$tmp/moved
while IFS= read -r -d '' file; do
  if grep -q -a -F -e "$build" -e "$src" -e "$tmp/prefix" "$file"; then
    fail "$file holds a build-machine path: $(strings "$file" | grep -F -e "$build" -e "$src" | head -3)"
  fi
done < <(find "$installed" -type f -print0)
ldd "$installed/bin/rodfab" > "$tmp/ldd" || fail "ldd"
grep -q "not found" "$tmp/ldd" && fail "unresolved libraries: $(grep 'not found' "$tmp/ldd")"
if grep "librodfab" "$tmp/ldd" | grep -v -q -F "$installed/"; then
  fail "stage libraries loaded from outside the installed tree: $(grep librodfab "$tmp/ldd")"
fi

mkdir "$tmp/elsewhere"
cd "$tmp/elsewhere" || fail "cd"
# A new user's first try: rodfab alone lists the commands (on stderr, exit 2: no command given).
"$installed/bin/rodfab" > "$tmp/usage" 2>&1
[ $? -eq 2 ] || fail "rodfab without arguments should exit 2"
for command in slice inspect profiles calibrate coupons; do
  grep -q "^  $command " "$tmp/usage" || fail "rodfab without arguments does not list '$command': $(cat "$tmp/usage")"
done
"$installed/bin/rodfab" profiles > "$tmp/profiles" 2>&1 || fail "profiles: $(cat "$tmp/profiles")"
grep -q "stratasys-objet500-connex3" "$tmp/profiles" || fail "profiles lists no bundled profile: $(cat "$tmp/profiles")"
"$installed/bin/rodfab" slice "$installed/share/rodfab/examples/unfolding-box.json" -o box.zip --quiet \
  > "$tmp/summary" 2> "$tmp/err" || fail "slice with the moved install: $(cat "$tmp/err")"
"$installed/bin/rodfab" slice "$installed/share/rodfab/examples/unfolding-box.json" -o blue.zip --dither blue --quiet \
  > /dev/null 2> "$tmp/err" || fail "blue-noise slice (the bundled mask) with the moved install: $(cat "$tmp/err")"
"$installed/bin/rodfab" inspect box.zip > "$tmp/inspect" 2>&1 || fail "inspect: $(cat "$tmp/inspect")"
grep -q "default-60C.json, sha256" "$tmp/summary" || fail "the summary names the calibration by name and SHA-256: $(cat "$tmp/summary")"

python3 - box.zip "$tmp" "$src" "$build" <<'PY' || fail "the manifest"
import json, sys, zipfile
job, roots = zipfile.ZipFile(sys.argv[1]), sys.argv[2:]
manifest = json.loads(job.read("manifest.json"))
def strings(v, path="manifest"):
    if isinstance(v, dict):
        for k, x in v.items(): yield from strings(x, f"{path}.{k}")
    elif isinstance(v, list):
        for i, x in enumerate(v): yield from strings(x, f"{path}[{i}]")
    elif isinstance(v, str):
        yield path, v
for path, s in strings(manifest):
    assert not s.startswith("/"), f"{path} is an absolute path: {s}"
    assert not any(r in s for r in roots), f"{path} names a folder of this machine: {s}"
assert manifest["calibration"]["file"] == "default-60C.json", manifest["calibration"]
assert len(manifest["calibration"]["sha256"]) == 64
assert manifest["metadata"]["design"] == "unfolding-box.json", manifest["metadata"]
for name in ("manifest.json", "report.html", "build.txt"):
    text = job.read(name)
    assert not any(r.encode() in text for r in roots), f"{name} names a folder of this machine"
PY

if [ -n "$make_cad" ]; then
  "$make_cad" box "$tmp/box.step" > /dev/null 2>&1 || fail "make_test_cad box"
  "$installed/bin/rodfab" rods-from-cad "$tmp/box.step" --diameter 1 -o box.json > "$tmp/out" 2>&1 ||
    fail "rods-from-cad with the moved install: $(cat "$tmp/out")"
  grep -q "12 rods" "$tmp/out" || fail "rods-from-cad summary: $(cat "$tmp/out")"
  # rodfab itself does not load OpenCASCADE; rods-from-cad runs the reader beside the stage libraries.
  grep -q "libTK" "$tmp/ldd" && fail "rodfab links OpenCASCADE: $(grep libTK "$tmp/ldd" | head -3)"
  reader=$(find "$installed" -name 'rodfab-cad-reader')
  [ -n "$reader" ] || fail "the CAD reader was not installed"
  ldd "$reader" | grep -q "not found" && fail "the installed CAD reader misses libraries: $(ldd "$reader" | grep 'not found')"
  mv "$reader" "$tmp/reader"
  "$installed/bin/rodfab" rods-from-cad "$tmp/box.step" --diameter 1 -o noreader.json > /dev/null 2> "$tmp/err"
  [ $? -eq 1 ] || fail "rods-from-cad without the CAD reader should exit 1"
  grep -q "the CAD reader .*rodfab-cad-reader did not start" "$tmp/err" || fail "the missing reader error: $(cat "$tmp/err")"
  [ -e noreader.json ] && fail "a design was written without the CAD reader"
  "$installed/bin/rodfab" profiles > /dev/null 2>&1 || fail "profiles without the CAD reader"
fi

# The data folder missing or misnamed: a clear error, nothing written.
RODFAB_DATA_DIR=$tmp/nowhere "$installed/bin/rodfab" profiles > /dev/null 2> "$tmp/err" && fail "a wrong RODFAB_DATA_DIR was accepted"
grep -q "RODFAB_DATA_DIR is '$tmp/nowhere'" "$tmp/err" || fail "the RODFAB_DATA_DIR error: $(cat "$tmp/err")"
RODFAB_DATA_DIR=$installed/share/rodfab "$installed/bin/rodfab" profiles > /dev/null 2>&1 || fail "RODFAB_DATA_DIR pointing at a data folder"
mv "$installed/share/rodfab" "$tmp/data"
"$installed/bin/rodfab" slice "$tmp/data/examples/unfolding-box.json" -o lost.zip --quiet > /dev/null 2> "$tmp/err" &&
  fail "a slice without the data folder succeeded"
grep -q "looked in:" "$tmp/err" && grep -q -F "$installed/share/rodfab" "$tmp/err" ||
  fail "the missing data folder error lists where it looked: $(cat "$tmp/err")"
[ -e lost.zip ] && fail "a job was written without the data folder"
RODFAB_DATA_DIR=$tmp/data "$installed/bin/rodfab" slice "$tmp/data/examples/unfolding-box.json" -o found.zip --quiet \
  > /dev/null 2> "$tmp/err" || fail "RODFAB_DATA_DIR override: $(cat "$tmp/err")"
echo "install: all checks passed"
