#!/usr/bin/env bash
# rodfab profiles and rodfab inspect from the command line: listings, exit codes, messages.
#   printer_profiles.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$rodfab" profiles > "$tmp/out" || fail "profiles: exit $?"
grep -q "stratasys-objet500-connex3 .*600 x 300 dpi" "$tmp/out" || fail "profiles does not list the Connex3: $(cat "$tmp/out")"
"$rodfab" profiles stratasys-objet500-connex3 > "$tmp/out" || fail "profiles NAME"
grep -q "x 600 dpi (image columns), y 300 dpi (image rows)" "$tmp/out" || fail "profile detail lacks the axes"
grep -q "VeroWhitePlus" "$tmp/out" || fail "profile detail lacks the materials"
"$rodfab" profiles --json | grep -q '"voxel_size_mm"' || fail "profiles --json"
"$rodfab" profiles "$src/printer_profiles/stratasys-objet500-connex3.json" > /dev/null || fail "profile by path"

"$rodfab" profiles objet-9000 2> "$tmp/err"
[ $? -eq 1 ] || fail "unknown profile: expected exit 1"
grep -q "objet-9000: no bundled profile of that name" "$tmp/err" || fail "unknown profile not named: $(cat "$tmp/err")"
# A name longer than a file name may be is still just an unknown profile, not a file system error.
long=$(printf 'p%.0s' $(seq 300))
"$rodfab" profiles "$long" 2> "$tmp/err"
[ $? -eq 1 ] || fail "300-character profile name: expected exit 1"
grep -q "$long: no bundled profile of that name" "$tmp/err" || fail "long profile name: $(cat "$tmp/err")"
sed 's/"x_dpi": 600/"x_dpi": 300/' "$src/printer_profiles/stratasys-objet500-connex3.json" > "$tmp/swapped.json"
"$rodfab" profiles "$tmp/swapped.json" 2> "$tmp/err"
[ $? -eq 1 ] || fail "bad profile: expected exit 1"
grep -q "swapped.json: resolution.voxel_size_mm\[0\]: .*x_dpi = 300" "$tmp/err" || fail "dpi mismatch not named: $(cat "$tmp/err")"

# Hostile profiles: each refused with exit 1, naming the file, the JSON path and what was expected.
hostile() {  # NAME PYTHON-EDIT PATTERN
  python3 - "$src/printer_profiles/stratasys-objet500-connex3.json" "$tmp/$1.json" "$2" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
exec(sys.argv[3])
open(sys.argv[2], "w").write(d if isinstance(d, str) else json.dumps(d))
PY
  timeout 20 "$rodfab" profiles "$tmp/$1.json" > /dev/null 2> "$tmp/err"
  local got=$?
  [ $got -eq 1 ] || fail "profile $1: exit $got, expected 1 ($(cat "$tmp/err"))"
  grep -q -- "$1.json: $3" "$tmp/err" || fail "profile $1: expected '$1.json: $3' in: $(cat "$tmp/err")"
}
hostile backslash 'd["build_file"]["name"] = "..\\evil.txt"' 'build_file.name: .*not a portable file name: it holds a path separator'
hostile drive 'd["build_file"]["name"] = "C:evil.txt"' "build_file.name: .*a drive letter"
hostile device 'd["build_file"]["name"] = "aux.txt"' "build_file.name: .*device name on Windows"
hostile case 'd["materials"][0]["name"] = "Vero"; d["materials"][1]["name"] = "VERO"' "materials\[1\].name: .*case-insensitive"
hostile report 'd["build_file"]["name"] = "REPORT.HTML"' 'build_file.name: "REPORT.HTML" is the name of the job report'
hostile padding 'd["image"]["padding_voxels"] = [100000, 16]' "image.padding_voxels\[0\]: expected a margin in voxels (an integer in 0..65536)"
hostile tray 'd["tray_mm"] = [2000, 390, 200]' "tray_mm: a full tray makes a layer image"
hostile columns 'd["tray_mm"] = [3000, 390, 200]' "tray_mm\\[0\\]: the tray holds 70921 image columns"
hostile density 'd["materials"][2]["density_g_per_ml"] = 1e300' "materials\[2\].density_g_per_ml: expected a density"
hostile duplicate 'd = json.dumps(d).replace("\"x_dpi\": 600", "\"x_dpi\": 600, \"x_dpi\": 300")' "resolution.x_dpi: this key appears twice"
hostile deep 'd = "[" * 200000 + "]" * 200000' ".*nested deeper than 64 levels"
mkfifo "$tmp/pipe.json"
timeout 20 "$rodfab" profiles "$tmp/pipe.json" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] && grep -q "pipe.json: is not a regular file" "$tmp/err" || fail "a named pipe as profile: $(cat "$tmp/err")"

mkdir "$tmp/empty-job"
"$rodfab" inspect "$tmp/empty-job" > "$tmp/out" 2> "$tmp/err"
[ $? -eq 1 ] || fail "inspect of an empty folder: expected exit 1"
grep -q "no manifest.json" "$tmp/err" || fail "missing manifest not reported: $(cat "$tmp/err")"
grep -q "verdict:       DEFECTIVE" "$tmp/out" || fail "no verdict"
head -c 1000 /dev/urandom > "$tmp/junk.zip"
"$rodfab" inspect --json "$tmp/junk.zip" > "$tmp/out"
[ $? -eq 1 ] || fail "inspect of junk: expected exit 1"
grep -q '"ok": false' "$tmp/out" || fail "inspect --json verdict"
"$rodfab" inspect "$tmp/none.zip" 2> "$tmp/err" > /dev/null
[ $? -eq 1 ] || fail "inspect of a missing job: expected exit 1"

# inspect never trusts the job: a real job, then hostile variants of it made by tests/cli/hostile_jobs.py.
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/box.zip" --quiet > /dev/null 2>&1 || fail "slice box.zip"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/box" --format dir --quiet > /dev/null 2>&1 || fail "slice box/"
"$rodfab" inspect "$tmp/box.zip" > "$tmp/out" 2>&1 || fail "inspect of a sound job: $(cat "$tmp/out")"
grep -q "verdict:       OK" "$tmp/out" || fail "no OK verdict"
"$rodfab" inspect --profile stratasys-objet500-connex3 "$tmp/box" > /dev/null 2>&1 || fail "inspect --profile NAME"
"$rodfab" inspect --profile "$src/printer_profiles/stratasys-objet500-connex3.json" "$tmp/box.zip" > /dev/null 2>&1 ||
  fail "inspect --profile FILE"
"$rodfab" inspect --profile objet-9000 "$tmp/box.zip" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] || fail "inspect --profile of an unknown name: expected exit 1"
grep -q "objet-9000: no bundled profile of that name" "$tmp/err" || fail "unknown --profile not named: $(cat "$tmp/err")"
python3 "$src/tests/cli/hostile_jobs.py" "$tmp/box.zip" "$tmp/box" "$tmp/h" 300 || fail "hostile_jobs.py"
# Standard input is a FIFO that never ends: reading it (a manifest naming /dev/stdin) would hang.
mkfifo "$tmp/never-ends"
exec 3<> "$tmp/never-ends"
hostile() {  # JOB PATTERN: exit 1 within 60 s, a defect matching PATTERN
  timeout 60 "$rodfab" inspect "$tmp/h/$1" <&3 > "$tmp/out" 2> "$tmp/err"
  local code=$?
  [ $code -eq 1 ] || fail "inspect $1: expected exit 1, got $code (124: it hung): $(cat "$tmp/err")"
  grep -q "verdict:       DEFECTIVE" "$tmp/out" || fail "inspect $1: no DEFECTIVE verdict"
  grep -q -- "$2" "$tmp/err" || fail "inspect $1: no defect matching '$2': $(cat "$tmp/err")"
}
hostile profile-stdin.zip 'profile-stdin.zip: manifest.json: profile.name: "/dev/stdin" cannot name any printer profile'
hostile profile-zero.zip 'profile.name: "/dev/zero" cannot name any printer profile'
hostile bomb.zip 'bomb.zip: bomb.bin: unexpected entry'
hostile huge.zip 'huge.zip: VeroWhitePlus_0000.bmp: declares 4026531840 bytes'
hostile dotdot.zip "dotdot.zip: ../../x: unsafe entry name: it has a '..' component"
hostile absolute.zip 'absolute.zip: /tmp/x: unsafe entry name: it is an absolute path'
hostile no-build.zip 'no-build.zip: build.txt: missing'
hostile no-rubbery.zip 'no-rubbery.zip: every TangoBlackPlus image is missing'
hostile deep.zip 'deep.zip: manifest.json: cannot be read: nested deeper than 64 arrays and objects'
hostile hidden-entry.zip 'hidden-entry.zip: not a consistent zip archive: .*_0000.bmp has a second local entry at byte'
hostile fifo 'fifo: VeroWhitePlus_0001.bmp: is a FIFO'
hostile zero-link 'zero-link: VeroWhitePlus_0001.bmp: is a symbolic link'
exec 3>&-
# The bomb is never inflated: inspect's peak memory stays far below its 300 MiB.
python3 - "$rodfab" "$tmp/h/bomb.zip" <<'PY' || fail "inspect of the deflate bomb"
import resource, subprocess, sys
run = subprocess.run([sys.argv[1], "inspect", sys.argv[2]], capture_output=True, timeout=60)
peak_mib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
if run.returncode != 1 or peak_mib > 150:
    sys.exit(f"exit {run.returncode}, peak {peak_mib:.0f} MiB (expected exit 1 under 150 MiB)")
PY
# The JSON report of a hostile job is valid JSON, even with unprintable names in it.
"$rodfab" inspect --json "$tmp/h/dotdot.zip" > "$tmp/out"
[ $? -eq 1 ] || fail "inspect --json of a hostile job: expected exit 1"
python3 -c 'import json,sys; r = json.load(open(sys.argv[1])); assert r["ok"] is False and r["defects"], r' "$tmp/out" ||
  fail "inspect --json output: $(head -c 300 "$tmp/out")"

# A job made with a profile file is not checked without that file: neither OK nor DEFECTIVE.
python3 - "$src/printer_profiles/stratasys-objet500-connex3.json" "$tmp/my-connex3.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
d["name"] = "my-connex3"
json.dump(d, open(sys.argv[2], "w"))
PY
"$rodfab" slice "$src/examples/unfolding-box.json" --profile "$tmp/my-connex3.json" --output "$tmp/mine.zip" > /dev/null 2>&1 ||
  fail "slice with a profile file"
"$rodfab" inspect "$tmp/mine.zip" > "$tmp/out" 2> "$tmp/err"
[ $? -eq 1 ] || fail "inspect of a profile file's job without it: expected exit 1"
grep -q "verdict:       NOT CHECKED" "$tmp/out" || fail "no NOT CHECKED verdict: $(cat "$tmp/out")"
grep -q 'not checked: .*mine.zip: made with printer profile "my-connex3", which is not bundled' "$tmp/err" ||
  fail "not-checked reason: $(cat "$tmp/err")"
grep -q "defect" "$tmp/err" && fail "defects reported for a sound job: $(cat "$tmp/err")"
"$rodfab" inspect --json "$tmp/mine.zip" > "$tmp/out"
python3 -c 'import json,sys; r = json.load(open(sys.argv[1])); assert r["ok"] is False and r["checked"] is False and not r["defects"] and "my-connex3" in r["not_checked"], r' \
  "$tmp/out" || fail "inspect --json of a profile file's job: $(head -c 400 "$tmp/out")"
"$rodfab" inspect --profile "$tmp/my-connex3.json" "$tmp/mine.zip" > "$tmp/out" 2>&1 || fail "inspect --profile FILE: $(cat "$tmp/out")"
grep -q "verdict:       OK" "$tmp/out" || fail "no OK verdict with the profile file"

# A profile file may take a bundled profile's name only as a copy of it (inspect checks a job against the
# bundled profile of its name: another tray under that name made jobs inspect called DEFECTIVE).
python3 - "$src/printer_profiles/stratasys-objet500-connex3.json" "$tmp/same-name.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
d["tray_mm"][0] -= 10
json.dump(d, open(sys.argv[2], "w"))
PY
"$rodfab" slice "$src/examples/unfolding-box.json" --profile "$tmp/same-name.json" --output "$tmp/same-name.zip" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] || fail "a profile file under a bundled name: expected exit 1"
grep -q 'same-name.json: name: "stratasys-objet500-connex3" is a bundled profile.s name, and this file is not that profile' "$tmp/err" ||
  fail "bundled name taken: $(cat "$tmp/err")"
[ -e "$tmp/same-name.zip" ] && fail "a job was written with a profile file under a bundled name"
python3 -c 'import json,sys; json.dump(json.load(open(sys.argv[1])), open(sys.argv[2], "w"), indent=1)' \
  "$src/printer_profiles/stratasys-objet500-connex3.json" "$tmp/copy.json"
"$rodfab" slice "$src/examples/unfolding-box.json" --profile "$tmp/copy.json" --output "$tmp/copy.zip" > /dev/null 2>&1 ||
  fail "a copy of a bundled profile (reformatted) is refused"
"$rodfab" inspect "$tmp/copy.zip" > /dev/null 2>&1 || fail "inspect of a job made with a copy of a bundled profile"

"$rodfab" inspect 2> /dev/null
[ $? -eq 2 ] || fail "inspect without a job: expected usage exit 2"
"$rodfab" profiles --bogus 2> /dev/null
[ $? -eq 2 ] || fail "unknown option: expected usage exit 2"
"$rodfab" inspect --help | grep -q "usage: rodfab inspect" || fail "inspect --help"
"$rodfab" profiles --help | grep -q "usage: rodfab profiles" || fail "profiles --help"
echo "printer_profiles CLI: all checks passed"
