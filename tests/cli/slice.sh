#!/usr/bin/env bash
# rodfab slice end to end: every bundled example into a job that inspect passes, identical bytes for
# any thread count and band size, a clean interrupt, and bad input that writes nothing. In sections,
# each its own ctest entry (cli_slice_SECTION): examples, force, interrupts, input (default: all).
#   slice.sh RODFAB SOURCE_DIR [SECTION ...]
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
only() {  # the folder holds exactly these names (nothing half-written, no hidden temporaries)
  local want
  want=$(printf '%s\n' "$@" | sort)
  [ "$(ls -A "$tmp/out" | sort)" = "$want" ] || fail "expected only '$*' in the output folder, found: $(ls -A "$tmp/out")"
}
mkdir "$tmp/out"

section_examples() {  # (bodies not indented: their here-documents end at column 0)
# Every bundled example, then inspect.
for design in "$src"/examples/*.json; do
  name=$(basename "$design" .json)
  "$rodfab" slice "$design" -o "$tmp/out/$name.zip" --quiet > "$tmp/summary" 2> "$tmp/err" ||
    fail "slice $name: $(cat "$tmp/err")"
  grep -q "layers:" "$tmp/summary" || fail "$name: no summary"
  "$rodfab" inspect "$tmp/out/$name.zip" > "$tmp/inspect" 2>&1 || fail "inspect $name: $(cat "$tmp/inspect")"
done
only arm-cast.zip buckling-spring.zip unfolding-box.zip

# The summary agrees with the job: voxels per material add up, print height = layers x 0.03 mm.
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/out/box.zip" --quiet --json > "$tmp/json" || fail "--json"
python3 - "$tmp/json" "$tmp/out/box.zip" <<'PY' || fail "summary vs manifest"
import json, sys, zipfile
s = json.load(open(sys.argv[1]))
m = json.loads(zipfile.ZipFile(sys.argv[2]).read("manifest.json"))
assert sum(x["voxels"] for x in s["materials"] if x["role"] != "support") == s["voxels"] > 0
assert abs(s["print_height_mm"] - 0.03 * s["layers"]) < 1e-9
assert s["ditherer"] == "white"                      # the bundled calibration's coupons were random-dithered
assert m["statistics"]["clamped_modulus"]["below_floor_voxels"] == s["clamped_moduli"]["below_floor"]
assert m["calibration"]["sha256"] and m["calibration"]["file"].endswith("default-60C.json")
# Each stage's CPU time: all three there, none negative, together within the process's over the bands.
t = s["seconds"]
assert set(t["cpu"]) == {"voxelize", "dither", "emit"}, t["cpu"]
assert all(v >= 0 for v in t["cpu"].values()) and t["cpu"]["emit"] > 0, t["cpu"]
assert sum(t["cpu"].values()) <= t["cpu_bands"] + 0.005, t
PY
rm "$tmp/out/box.zip"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/out/box.zip" > "$tmp/text" || fail "slice, the summary"
grep -Eq "^CPU: +[0-9.]+ s voxelize, [0-9.]+ s map \+ dither, [0-9.]+ s emit; [0-9.]+ s all threads$" "$tmp/text" ||
  fail "no CPU line in the summary: $(cat "$tmp/text")"
rm "$tmp/out/box.zip"

# The same bytes whatever the machine's time zone (zip stores its entries' local times; POSIX zone strings
# need no tzdata), and the entries dated noon, 1 January 2020, as Python's zipfile reads them. One job
# name in three folders: the manifest and previews record the name.
for zone in UTC0 JST-9 PST8PDT; do
  mkdir -p "$tmp/tz/$zone"
  TZ=$zone "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/tz/$zone/box.zip" --quiet > /dev/null 2> "$tmp/err" ||
    fail "slice in TZ=$zone: $(cat "$tmp/err")"
done
cmp -s "$tmp/tz/UTC0/box.zip" "$tmp/tz/JST-9/box.zip" && cmp -s "$tmp/tz/UTC0/box.zip" "$tmp/tz/PST8PDT/box.zip" ||
  fail "the job's bytes depend on the time zone"
python3 -c "import sys, zipfile; assert {i.date_time for i in zipfile.ZipFile(sys.argv[1]).infolist()} == {(2020, 1, 1, 12, 0, 0)}" \
  "$tmp/tz/JST-9/box.zip" || fail "entries not dated 2020-01-01 12:00"
rm -r "$tmp/tz"

# Determinism: the same bytes for 1 and 2 threads and different band sizes, per ditherer (same job
# name in two folders: the name is printed in the previews).
mkdir "$tmp/1" "$tmp/2" "$tmp/3"
for dither in white blue error-diffusion; do
  "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/1/job.zip" --dither $dither --seed 7 --threads 1 --quiet > /dev/null ||
    fail "$dither, 1 thread"
  "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/2/job.zip" --dither $dither --seed 7 --threads 2 --band-layers 13 --quiet > /dev/null ||
    fail "$dither, 2 threads"
  cmp -s "$tmp/1/job.zip" "$tmp/2/job.zip" || fail "$dither: jobs differ between 1 thread and 2 threads with other bands"
  "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/3/job.zip" --dither $dither --seed 8 --quiet > /dev/null || fail "$dither, seed 8"
  cmp -s "$tmp/1/job.zip" "$tmp/3/job.zip" && fail "$dither: seeds 7 and 8 gave the same job"
  rm -f "$tmp"/[123]/job.zip
done

# Error diffusion within a budget 2 % over its estimate (as --json gives it): the same bands and bytes as
# without one. The budget is also the process's data limit, so an estimate below what the slice really
# allocates would end in out of memory here (tidy10 tightened it: unfolding-box 541 -> 461 MB, peak 201 MB).
for design in unfolding-box buckling-spring; do
  "$rodfab" slice "$src/examples/$design.json" -o "$tmp/1/job.zip" --dither error-diffusion --seed 7 --threads 2 --quiet --json > "$tmp/json" ||
    fail "$design, error diffusion"
  read -r estimate bands < <(python3 -c "import json, sys; m = json.load(open(sys.argv[1]))['memory']; print(m['estimate_bytes'], m['band_layers'])" "$tmp/json")
  budget=$((estimate + estimate / 50))
  "$rodfab" slice "$src/examples/$design.json" -o "$tmp/2/job.zip" --dither error-diffusion --seed 7 --threads 2 --quiet --json \
    --max-memory "$budget" > "$tmp/json" 2> "$tmp/err" || fail "$design, error diffusion in $budget bytes (estimate $estimate): $(cat "$tmp/err")"
  python3 -c "import json, sys; assert json.load(open(sys.argv[1]))['memory']['band_layers'] == int(sys.argv[2])" "$tmp/json" "$bands" ||
    fail "$design: other bands than $bands in $budget bytes"
  cmp -s "$tmp/1/job.zip" "$tmp/2/job.zip" || fail "$design: a budget changed the job"
  rm -f "$tmp"/[12]/job.zip
done

# "random" (the published pipeline's word, as calibration data records it) is white, as in coupons.
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/1/job.zip" --dither random --seed 3 --quiet > /dev/null || fail "--dither random"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/2/job.zip" --dither white --seed 3 --quiet > /dev/null || fail "--dither white"
cmp -s "$tmp/1/job.zip" "$tmp/2/job.zip" || fail "--dither random is not --dither white"
rm -f "$tmp"/[12]/job.zip

# PNG in a folder, explicit support: inspect passes.
"$rodfab" slice "$src/examples/arm-cast.json" -o "$tmp/out/cast" --format dir --image-format png --support explicit --quiet > /dev/null 2> "$tmp/err" ||
  fail "png/dir/explicit: $(cat "$tmp/err")"
ls "$tmp/out/cast" | grep -q "^FullCure705_0000.png$" || fail "explicit support wrote no support bitmaps: $(ls "$tmp/out/cast" | head)"
"$rodfab" inspect "$tmp/out/cast" > /dev/null 2>&1 || fail "inspect png/dir job"
rm -rf "$tmp/out/cast"

}

section_force() {  # (bodies not indented: their here-documents end at column 0)
# An existing job is kept unless --force.
before=$(sha256sum "$tmp/out/arm-cast.zip")
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/out/arm-cast.zip" --quiet > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] || fail "existing job: expected exit 1"
grep -q "arm-cast.zip" "$tmp/err" || fail "existing job not named: $(cat "$tmp/err")"
[ "$(sha256sum "$tmp/out/arm-cast.zip")" = "$before" ] || fail "existing job was modified"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/out/arm-cast.zip" --force --quiet > /dev/null || fail "--force"
only arm-cast.zip buckling-spring.zip unfolding-box.zip

# --force replaces only rodfab jobs: a user's folder (named with or without a slash), a file, a
# foreign zip, a link to a job and a job folder with a file added are refused, named, and left byte for byte.
mkdir -p "$tmp/f/mydata/sub" "$tmp/f/project"
echo "my notes" > "$tmp/f/mydata/notes.txt"; echo "{}" > "$tmp/f/mydata/sub/manifest.json"
echo "chapter 1" > "$tmp/f/project/thesis.tex"; echo "not a zip" > "$tmp/f/thesis.zip"
python3 -c "import zipfile, sys; z = zipfile.ZipFile(sys.argv[1], 'w'); z.writestr('manifest.json', '{\"format\": \"other/1\"}'); z.close()" "$tmp/f/other.zip"
cp "$tmp/out/arm-cast.zip" "$tmp/f/job.zip"; ln -s job.zip "$tmp/f/link.zip"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/f/jobdir" --format dir --quiet > /dev/null || fail "dir job"
echo "mine" > "$tmp/f/jobdir/mine.txt"
tree() { (cd "$tmp/f" && find . -printf '%p %y %l\n' | sort && find . -type f -exec sha256sum {} + | sort); }
before=$(tree)
refused() {  # TARGET PATTERN
  "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/f/$1" --force --quiet > /dev/null 2> "$tmp/err"
  local got=$?
  [ $got -eq 1 ] || fail "--force over $1: exit $got, expected 1 ($(cat "$tmp/err"))"
  grep -q -- "$2" "$tmp/err" || fail "--force over $1: expected '$2' in: $(cat "$tmp/err")"
  grep -q "rodfab replaces only its own jobs" "$tmp/err" || fail "--force over $1: no reason given: $(cat "$tmp/err")"
  [ "$(tree)" = "$before" ] || fail "--force over $1 changed the folder: $(diff <(echo "$before") <(tree))"
}
refused mydata "mydata: is a folder without a rodfab job manifest"
refused mydata/ "mydata: is a folder without a rodfab job manifest"
refused project/ "project: is a folder"
refused thesis.zip "thesis.zip: is a file that is not a zip archive"
refused other.zip "other.zip: is a zip archive whose manifest.json is not a rodfab job manifest"
refused link.zip "link.zip: is a symbolic link"
refused jobdir "'mine.txt', which is not part of that job"
# A rodfab job of either kind is replaced by one of either kind, leaving nothing else.
rm "$tmp/f/jobdir/mine.txt"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/f/jobdir" --force --quiet > /dev/null || fail "zip over a dir job"
[ -f "$tmp/f/jobdir" ] && "$rodfab" inspect "$tmp/f/jobdir" > /dev/null || fail "the replacing zip job"
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/f/job.zip" --format dir --force --quiet > /dev/null || fail "dir over a zip job"
[ -d "$tmp/f/job.zip" ] && "$rodfab" inspect "$tmp/f/job.zip" > /dev/null || fail "the replacing dir job"
[ -z "$(ls -A "$tmp/f" | grep rodfab-partial)" ] || fail "temporaries left: $(ls -A "$tmp/f")"

}

section_interrupts() {  # (bodies not indented: their here-documents end at column 0)
# Interrupt: SIGINT once the first band is done; exit 130, nothing left behind.
"$rodfab" slice "$src/examples/buckling-spring.json" -o "$tmp/out/int.zip" --threads 1 --band-layers 8 > /dev/null 2> "$tmp/progress" &
pid=$!
for _ in $(seq 1 200); do grep -q "layers" "$tmp/progress" && break; sleep 0.05; done
kill -INT $pid
wait $pid
code=$?
[ $code -eq 130 ] || fail "interrupt: exit $code, expected 130 ($(cat "$tmp/progress"))"
grep -q "interrupted by SIGINT; nothing was written" "$tmp/progress" || fail "interrupt not reported: $(cat "$tmp/progress")"
only arm-cast.zip buckling-spring.zip unfolding-box.zip

# SIGINT or SIGTERM after the last band (the job is being zipped and verified): still 130/143 and no job.
# The window is the spring's finalize (~0.2 s): its progress is read through a FIFO as it is written
# (shell builtins, no process started per look), so the signal follows "(100%)" within a scheduler tick
# even on a loaded machine, where polling the file with grep every 10 ms once missed it.
mkfifo "$tmp/late.fifo"
for sig in INT TERM; do
  : > "$tmp/progress"  # a fresh file: the check below must not see the last run's progress
  "$rodfab" slice "$src/examples/buckling-spring.json" -o "$tmp/out/late.zip" --threads 1 --band-layers 8 > /dev/null 2> "$tmp/late.fifo" &
  pid=$!
  exec {progress}< "$tmp/late.fifo"
  while IFS= read -r -u $progress line; do
    printf '%s\n' "$line" >> "$tmp/progress"
    [[ $line == *"(100%)"* ]] && break
  done
  kill -$sig $pid
  cat <&$progress >> "$tmp/progress"  # the rest, to the writer's end
  exec {progress}<&-
  wait $pid
  code=$?
  want=$([ $sig = INT ] && echo 130 || echo 143)
  [ $code -eq $want ] || fail "SIG$sig after the last band: exit $code, expected $want ($(cat "$tmp/progress"))"
  grep -q "nothing was written" "$tmp/progress" || fail "late SIG$sig not reported: $(cat "$tmp/progress")"
  only arm-cast.zip buckling-spring.zip unfolding-box.zip
done
rm "$tmp/late.fifo"

# inspect stops by itself at a signal (every layer checks for one), not by the watchdog's cut after 0.6 s:
# two thin posts 90 mm tall at opposite corners of 80 x 80 mm, 3,000 layers of 1,900 x 950 px (about a
# second to inspect).
cat > "$tmp/posts.json" <<'JSON'
{ "format": "rodfab.design/1", "units": "mm",
  "rods": [ { "name": "a", "centerline": { "degree": 1, "knots": [0, 0, 1, 1], "points": [[0,0,0],[0,0,90]] },
              "section": { "shape": "circle", "diameter": 1 }, "modulus": 50 },
            { "name": "b", "centerline": { "degree": 1, "knots": [0, 0, 1, 1], "points": [[80,80,0],[80,80,90]] },
              "section": { "shape": "circle", "diameter": 1 }, "modulus": 50 } ] }
JSON
"$rodfab" slice "$tmp/posts.json" -o "$tmp/posts.zip" --quiet > /dev/null || fail "slice the posts"
"$rodfab" inspect "$tmp/posts.zip" > /dev/null 2> "$tmp/inspect-err" &
pid=$!
# Once its handlers are installed (SigCgt holds SIGINT, bit 2): a loaded machine can take longer than
# the sleep below to start the program, and a signal before then ends it without a word.
for _ in $(seq 1 500); do
  mask=$(awk '/^SigCgt:/ { print $2 }' "/proc/$pid/status" 2> /dev/null)
  [ -n "$mask" ] && (( 16#$mask & 2 )) && break
  sleep 0.01
done
sleep 0.3
kill -INT $pid
wait $pid
code=$?
[ $code -eq 130 ] || fail "inspect interrupted: exit $code, expected 130 ($(cat "$tmp/inspect-err"))"
grep -q "rodfab inspect: interrupted by SIGINT" "$tmp/inspect-err" || fail "inspect was cut short: $(cat "$tmp/inspect-err")"

# SIGKILL leaves a staging folder; the next job in that folder removes it, whatever its name, but keeps
# a live writer's folder (its lock held: here by flock(1)) and names that only look like ours.
rm -f "$tmp/progress"
"$rodfab" slice "$src/examples/buckling-spring.json" -o "$tmp/out/killed.zip" --threads 1 --band-layers 8 > /dev/null 2> "$tmp/progress" &
pid=$!
for _ in $(seq 1 2000); do grep -q "layers" "$tmp/progress" 2> /dev/null && break; sleep 0.05; done
kill -KILL $pid
wait $pid 2> /dev/null
ls -A "$tmp/out" | grep -q "^\.killed\.zip\.rodfab-partial-$pid-" || fail "SIGKILL left no staging folder to clean: $(ls -A "$tmp/out")"
mkdir "$tmp/out/.held.zip.rodfab-partial-999999-0" "$tmp/out/.lookalike.rodfab-partial-x"
touch "$tmp/out/.held.zip.rodfab-partial-999999-0/.lock"
flock "$tmp/out/.held.zip.rodfab-partial-999999-0/.lock" sleep 60 &
holder=$!
sleep 0.3
"$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/out/next.zip" --quiet > /dev/null || fail "the job after SIGKILL"
kill $holder
only arm-cast.zip buckling-spring.zip unfolding-box.zip next.zip .held.zip.rodfab-partial-999999-0 .lookalike.rodfab-partial-x
rm -r "$tmp/out/next.zip" "$tmp/out/.held.zip.rodfab-partial-999999-0" "$tmp/out/.lookalike.rodfab-partial-x"

}

section_input() {  # (bodies not indented: their here-documents end at column 0)
# A design whose file name is not UTF-8 (recorded in the manifest): a job, not a JSON encoding error.
odd=$(printf 'box\377.json')
cp "$src/examples/unfolding-box.json" "$tmp/$odd"
"$rodfab" slice "$tmp/$odd" -o "$tmp/out/odd.zip" --quiet > /dev/null 2> "$tmp/err" || fail "a non-UTF-8 design name: $(cat "$tmp/err")"
"$rodfab" inspect "$tmp/out/odd.zip" > /dev/null || fail "the job of a non-UTF-8 design name"
rm "$tmp/out/odd.zip"

# Moduli beyond the float range: refused by the design reader or sliced, never a crash or a leftover.
cat > "$tmp/huge.json" <<'JSON'
{ "format": "rodfab.design/1", "units": "mm",
  "rods": [ { "name": "a", "centerline": { "degree": 1, "knots": [0,0,1,1], "points": [[0,0,0],[3,0,0]] },
              "section": { "shape": "circle", "diameter": 1 }, "modulus": 4e38 },
            { "name": "b", "centerline": { "degree": 1, "knots": [0,0,1,1], "points": [[0,2,0],[3,2,0]] },
              "section": { "shape": "circle", "diameter": 1 }, "modulus": 50 } ] }
JSON
"$rodfab" slice "$tmp/huge.json" -o "$tmp/out/huge.zip" --quiet > /dev/null 2> "$tmp/err"
code=$?
if [ $code -eq 0 ]; then
  "$rodfab" inspect "$tmp/out/huge.zip" > /dev/null || fail "the huge-modulus job does not inspect clean"
  rm "$tmp/out/huge.zip"
else
  [ $code -eq 1 ] && grep -q "huge.json" "$tmp/err" || fail "huge moduli: exit $code ($(cat "$tmp/err"))"
fi
only arm-cast.zip buckling-spring.zip unfolding-box.zip

# Bad input: a clear message, non-zero exit, nothing written.
expect() {  # CODE PATTERN ARGS...
  local code=$1 pattern=$2; shift 2
  "$rodfab" slice "$@" > /dev/null 2> "$tmp/err"
  local got=$?
  [ $got -eq "$code" ] || fail "slice $*: exit $got, expected $code ($(cat "$tmp/err"))"
  grep -q -- "$pattern" "$tmp/err" || fail "slice $*: expected '$pattern' in: $(cat "$tmp/err")"
  only arm-cast.zip buckling-spring.zip unfolding-box.zip
}
expect 1 "missing.json: cannot open" "$tmp/missing.json" -o "$tmp/out/x.zip"
echo '{ "format": "rodfab.design/1", "units": "mm", "rods": [ { "name": "a", "modulus": -3 } ] }' > "$tmp/bad.json"
expect 1 "bad.json: rods\[0\]" "$tmp/bad.json" -o "$tmp/out/x.zip"
expect 1 "no-such-printer" "$src/examples/unfolding-box.json" -o "$tmp/out/x.zip" --profile no-such-printer
expect 1 "no/such/dir: the output directory does not exist" "$src/examples/unfolding-box.json" -o "$tmp/out/no/such/dir/x.zip"
expect 1 "arm-cast.zip: is not a directory" "$src/examples/unfolding-box.json" -o "$tmp/out/arm-cast.zip/x.zip"
expect 1 "/proc: cannot write the job there" "$src/examples/unfolding-box.json" -o /proc/rodfab-test-job.zip
expect 1 "missing-cal.json" "$src/examples/unfolding-box.json" -o "$tmp/out/x.zip" --calibration "$tmp/missing-cal.json"
expect 2 "--dither" "$src/examples/unfolding-box.json" -o "$tmp/out/x.zip" --dither ordered
expect 2 "--format" "$src/examples/unfolding-box.json" -o "$tmp/out/x.zip" --format tar
expect 2 "output" "$src/examples/unfolding-box.json"
# An empty option ("$UNSET") is a usage error, not a file that cannot be written.
expect 2 "^rodfab slice: --output: expected a value, got an empty string" "$src/examples/unfolding-box.json" -o ""
expect 2 "^rodfab slice: --profile: expected a value" "$src/examples/unfolding-box.json" -o "$tmp/out/x.zip" --profile ""
# A 600 mm rod does not fit the 490 mm tray: refused with the overhang in mm.
cat > "$tmp/long.json" <<'JSON'
{ "format": "rodfab.design/1", "units": "mm",
  "rods": [ { "name": "long", "centerline": { "degree": 1, "knots": [0,0,1,1], "points": [[0,0,0],[600,0,0]] },
              "section": { "shape": "circle", "diameter": 1 }, "modulus": 50 } ] }
JSON
expect 1 "long.json: the part (.*) does not fit .* mm along x.*no job was written" "$tmp/long.json" -o "$tmp/out/x.zip"
# Rods thinner than any voxel leave nothing to print: the design is named.
sed 's/"diameter": 1 }/"diameter": 1e-6 }/' "$tmp/long.json" | sed 's/600,0,0/6,0,0/' > "$tmp/thin.json"
expect 1 "thin.json: the part has no voxels.*thinner than its voxels" "$tmp/thin.json" -o "$tmp/out/x.zip"
# Designs longer than the grid holds (16777216 voxels along an axis): refused naming the rod (index and name),
# the field that makes it so, the extent and the limit in mm at the printer's voxel; nothing written. A
# diameter of 1e308 mm, a control point at 1e8 mm (within the reader's +-1e9 mm), two rods far apart
# (neither too long alone), and a control point at 1e12 mm, which the design reader refuses first.
grid_design() {  # FILE ROD...: a design of the rods given (JSON objects), each E 50 MPa
  local IFS=, name=$1
  shift
  echo "{ \"format\": \"rodfab.design/1\", \"units\": \"mm\", \"rods\": [ $* ] }" > "$tmp/$name.json"
}
rod() {  # NAME DIAMETER POINTS
  echo "{ \"name\": \"$1\", \"centerline\": $3, \"section\": { \"shape\": \"circle\", \"diameter\": $2 }, \"modulus\": 50 }"
}
line='{ "degree": 1, "knots": [0,0,1,1], "points": [[0,0,0],[3,0,0]] }'
bow() { echo "{ \"degree\": 2, \"knots\": [0,0,0,1,1,1], \"points\": [[0,0,0],[1,0,$1],[2,0,0]] }"; }
grid_design fat "$(rod a 1 "$line")" "$(rod fat 1e6 "$line")"
expect 1 'fat.json: the design spans 1e+06 mm along x: rods\[1\] ("fat") spans 1e+06 mm along x (its section.diameter of 1e+06 mm); expected at most 709676 mm along x (16777216 voxels along an axis at this printer.s voxel of 0.0423 mm)' "$tmp/fat.json" -o "$tmp/out/x.zip"
# A section so wide that the rod's bounds would overflow the double's range: the design reader refuses it.
grid_design wide "$(rod a 1 "$line")" "$(rod wide 1.7e308 '{ "degree": 1, "knots": [0,0,1,1], "points": [[0,0,0],[3,3,3]] }')"
expect 1 'wide.json: rods\[1\].section.diameter: expected a diameter in mm of at most 1e6 (a kilometre), got 1.7e.308' "$tmp/wide.json" -o "$tmp/out/x.zip"
grid_design tall "$(rod a 1 "$line")" "$(rod tall 1 "$(bow 1e8)")"
expect 1 'tall.json: the design spans 5e+07 mm along z: rods\[1\] ("tall") spans 5e+07 mm along z (its control points centerline.points\[0\] at z = 0 mm and centerline.points\[1\] at z = 1e+08 mm); expected at most 503316 mm along z (16777216 voxels along an axis at this printer.s voxel of 0.03 mm)' "$tmp/tall.json" -o "$tmp/out/x.zip"
grid_design apart "$(rod low 1 '{ "degree": 1, "knots": [0,0,1,1], "points": [[0,0,-4e5],[3,0,-4e5]] }')" "$(rod mid 1 "$line")" \
  "$(rod high 1 '{ "degree": 1, "knots": [0,0,1,1], "points": [[0,0,4e5],[3,0,4e5]] }')"
expect 1 'apart.json: the design spans 800001 mm along z: rods\[0\] ("low") reaches down to z = -4[0-9]* mm and rods\[2\] ("high") up to z = 4[0-9]* mm; expected at most 503316 mm along z' "$tmp/apart.json" -o "$tmp/out/x.zip"
grid_design far "$(rod a 1 "$line")" "$(rod far 1 "$(bow 1e12)")"
expect 1 'far.json: rods\[1\].centerline.points\[1\]: expected coordinates within +-1e9 mm' "$tmp/far.json" -o "$tmp/out/x.zip"
# A budget below the job writer's fixed share (images, previews, the process: ~100 MB, more for a larger part):
# refused as such, without suggesting --band-layers, which cannot help.
expect 1 "writing the job of .* no band size makes that smaller: raise --max-memory to at least" "$src/examples/buckling-spring.json" -o "$tmp/out/x.zip" --max-memory 100M
grep -q -- "--band-layers" "$tmp/err" && fail "a budget under the writer's share suggested --band-layers: $(cat "$tmp/err")"
# A budget above the writer's share but below what the smallest band needs (white noise, mapped as it dithers:
# 135 MiB in bands of 1 layer, 2026-12-03): refused naming the design, its
# images and the smallest band size tried, with a --max-memory value that would do.
expect 1 "slicing buckling-spring.json (312 rod(s), layer images of 800 x 396 pixels) needs about .* even in bands of 1 layer (the smallest band size tried), more than the memory budget of 125 MiB .* raise --max-memory to at least [0-9]*M" "$src/examples/buckling-spring.json" -o "$tmp/out/x.zip" --max-memory 125M
grep -q -- "--band-layers" "$tmp/err" && fail "a budget no band size fits suggested --band-layers: $(cat "$tmp/err")"
# A band size given that is over the budget where a smaller one fits: the refusal names the job's own
# image size and the largest band size that fits, and that one slices within the budget.
expect 1 "slicing arm-cast.json (191 rod(s), layer images of 1792 x 753 pixels) in bands of 48 layers needs about .*; use --band-layers [0-9]* (the largest that fits)" "$src/examples/arm-cast.json" -o "$tmp/out/x.zip" --band-layers 48 --max-memory 300M --quiet
fits=$(sed -n 's/.*use --band-layers \([0-9]*\) (the largest that fits).*/\1/p' "$tmp/err")
"$rodfab" slice "$src/examples/arm-cast.json" -o "$tmp/fits.zip" --band-layers "$fits" --max-memory 300M --quiet > /dev/null 2> "$tmp/err" ||
  fail "the band size suggested ($fits) does not fit: $(cat "$tmp/err")"
rm -f "$tmp/fits.zip"
# A profile whose build file would escape the job folder on Windows.
sed 's/"name": "build.txt"/"name": "..\\\\evil.txt"/' "$src/printer_profiles/stratasys-objet500-connex3.json" > "$tmp/evil-profile.json"
expect 1 "evil-profile.json: build_file.name: .* is not a portable file name" "$src/examples/unfolding-box.json" -o "$tmp/out/x.zip" --profile "$tmp/evil-profile.json"
}

# The other sections need three jobs in the output folder (any rodfab job will do): one slice, copied.
setup_jobs() {
  "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/out/unfolding-box.zip" --quiet > /dev/null 2> "$tmp/err" ||
    fail "slice unfolding-box: $(cat "$tmp/err")"
  cp "$tmp/out/unfolding-box.zip" "$tmp/out/arm-cast.zip"
  cp "$tmp/out/unfolding-box.zip" "$tmp/out/buckling-spring.zip"
}

sections=("${@:3}")
[ ${#sections[@]} -gt 0 ] || sections=(examples force interrupts input)
for section in "${sections[@]}"; do
  declare -F "section_$section" > /dev/null || fail "no section '$section' (examples, force, interrupts, input)"
  [ "$section" = examples ] || [ -e "$tmp/out/arm-cast.zip" ] || setup_jobs
  "section_$section"
done
"$rodfab" slice --help | grep -q "usage: rodfab slice" || fail "--help"
echo "slice ${sections[*]}: ok"
