#!/usr/bin/env bash
# The J750/J850 through GrabCAD Voxel Print: slice, coupons and voxelize with the profile, the .gcvf
# and its folder form decoded by an independent reader (gcvf_decode.py: zlib + xml.etree), the same
# bytes for any thread count and band size, print modes, calibration materials, inspect's defects.
#   gcvf.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
decode() { python3 "$here/gcvf_decode.py" "$@"; }
j7=stratasys-j750-j850

# A 3 mm rod, modulus 8 .. 120 MPa: both materials, ~60 small layers.
cat > "$tmp/rod.json" <<'EOF'
{"format": "rodfab.design/1", "units": "mm", "rods": [{"name": "edge-0",
 "centerline": {"degree": 3, "knots": [0, 0, 0, 0, 1, 1, 1, 1], "points": [[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0]]},
 "section": {"shape": "circle", "diameter": 1.5}, "normal": [0, 0, 1],
 "modulus": {"degree": 1, "knots": [0, 0, 0.5, 1, 1], "values": [8, 120, 40]}}]}
EOF

"$rodfab" profiles > "$tmp/out" || fail "profiles"
grep -q "$j7 .*600 x 300 dpi, 0.027 mm layers" "$tmp/out" || fail "profiles does not list the J750: $(cat "$tmp/out")"
"$rodfab" profiles $j7 > "$tmp/out" || fail "profiles $j7"
grep -q "print mode:    high-mix         0.014 mm layers" "$tmp/out" || fail "print modes not shown: $(cat "$tmp/out")"
grep -q "GrabCAD Voxel Print" "$tmp/out" || fail "job format not shown"

# Slice: a .gcvf, the stand-in calibration named in the summary, on stderr and in the manifest.
"$rodfab" slice "$tmp/rod.json" -o "$tmp/rod.gcvf" --profile $j7 --quiet > "$tmp/summary" 2> "$tmp/err" || fail "slice: $(cat "$tmp/err")"
grep -q "WARNING: stand-in calibration: .*VeroWhitePlus / TangoBlackPlus.*VeroUltraWhite / Agilus30Black" "$tmp/summary" ||
  fail "no stand-in warning in the summary: $(cat "$tmp/summary")"
grep -q "warning: stand-in calibration" "$tmp/err" || fail "no stand-in warning on stderr"
decode "$tmp/rod.gcvf" --expect-thickness-nm 27000 > "$tmp/decoded" || fail "independent decoder refused the .gcvf"
python3 - "$tmp/rod.gcvf" "$tmp/decoded" <<'PY' || fail "manifest vs decoded job"
import json, sys, zipfile
z = zipfile.ZipFile(sys.argv[1])
m = json.loads(z.read("manifest.json"))
d = json.load(open(sys.argv[2]))
assert m["calibration"]["warning"].startswith("stand-in calibration")
assert not any(w.startswith("/") and len(w) > 1 for w in m["calibration"]["warning"].split()), "the manifest names the calibration by file name only"
assert m["calibration"]["materials"] == {"rigid": "VeroWhitePlus", "rubbery": "TangoBlackPlus"}
assert m["profile"]["print_mode"] == "high-speed" and m["image"]["bit_depth"] == 32
assert d["voxels"]["VeroUltraWhite"] > 0 and d["voxels"]["Agilus30Black"] > 0, d
for name, n in d["voxels"].items():
    assert m["statistics"]["materials"][name]["voxels"] == n
assert m["layer_count"] == d["layers"] and [m["image"]["width"], m["image"]["height"]] == [d["width"], d["height"]]
assert "build.txt" not in z.namelist()
PY
"$rodfab" inspect "$tmp/rod.gcvf" > "$tmp/inspect" 2>&1 || fail "inspect: $(cat "$tmp/inspect")"

# Same bytes for any thread count and band size; the folder form holds the same files.
mkdir "$tmp/t1" "$tmp/t2"  # the same job name: the previews' title shows it
"$rodfab" slice "$tmp/rod.json" -o "$tmp/t1/rod.gcvf" --profile $j7 --threads 1 --band-layers 3 --quiet > /dev/null 2>&1 || fail "slice 1 thread"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/t2/rod.gcvf" --profile $j7 --threads 2 --band-layers 17 --quiet > /dev/null 2>&1 || fail "slice 2 threads"
cmp -s "$tmp/rod.gcvf" "$tmp/t1/rod.gcvf" || fail "1 thread, 3-layer bands: other bytes"
cmp -s "$tmp/rod.gcvf" "$tmp/t2/rod.gcvf" || fail "2 threads, 17-layer bands: other bytes"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/rod-dir" --format dir --profile $j7 --quiet > /dev/null 2>&1 || fail "slice --format dir"
decode "$tmp/rod-dir" --expect-thickness-nm 27000 > /dev/null || fail "independent decoder refused the folder form"
python3 - "$tmp/rod.gcvf" "$tmp/rod-dir" <<'PY' || fail "the folder form's layers or ConfigFile.xml differ from the zip's"
import os, sys, zipfile
z = zipfile.ZipFile(sys.argv[1])
for n in z.namelist():
    if n in ("manifest.json", "report.html") or n.startswith("previews/"): continue  # they name the job and its form
    assert open(os.path.join(sys.argv[2], n), "rb").read() == z.read(n), n
PY
"$rodfab" inspect "$tmp/rod-dir" > /dev/null 2>&1 || fail "inspect the folder form"

# --force replaces only a rodfab job.
"$rodfab" slice "$tmp/rod.json" -o "$tmp/rod.gcvf" --profile $j7 --quiet 2> "$tmp/err"
[ $? -eq 1 ] && grep -q "use --force" "$tmp/err" || fail "an existing .gcvf was not refused without --force"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/rod.gcvf" --profile $j7 --quiet --force > /dev/null 2>&1 || fail "--force"

# High-mix mode: 14 um layers, the mode in the manifest, and inspect applies it.
"$rodfab" slice "$tmp/rod.json" -o "$tmp/mix.gcvf" --profile $j7 --print-mode high-mix --quiet > /dev/null 2>&1 || fail "high-mix"
decode "$tmp/mix.gcvf" --expect-thickness-nm 14000 > "$tmp/mix" || fail "decoder refused the high-mix job"
python3 -c "import json,sys; a=json.load(open('$tmp/decoded')); b=json.load(open('$tmp/mix')); assert b['layers'] > 1.8 * a['layers'], (a, b)" ||
  fail "high-mix should have about twice the layers"
"$rodfab" inspect "$tmp/mix.gcvf" > /dev/null 2>&1 || fail "inspect high-mix"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/x.gcvf" --profile $j7 --print-mode ultra --quiet 2> "$tmp/err"
[ $? -eq 2 ] && grep -q "\-\-print-mode: expected one of the .* profile's modes: high-speed, high-mix, got 'ultra'" "$tmp/err" ||
  fail "unknown mode: $(cat "$tmp/err")"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/x.gcvf" --profile $j7 --support explicit --quiet 2> "$tmp/err"
[ $? -ne 0 ] && grep -q "GrabCAD" "$tmp/err" || fail "explicit support accepted for a gcvf job: $(cat "$tmp/err")"
[ ! -e "$tmp/x.gcvf" ] || fail "a refused job left a file"

# Calibration materials: another pair is refused unless forced; a recorded match is silent.
cp "$src/examples/calibration/default-60C.json" "$tmp/connex-cal.json"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/x.gcvf" --profile $j7 --calibration "$tmp/connex-cal.json" --quiet 2> "$tmp/err"
[ $? -eq 1 ] || fail "a calibration for other materials was not refused"
grep -q "measured on VeroWhitePlus / TangoBlackPlus.*--allow-calibration-materials-mismatch" "$tmp/err" || fail "refusal: $(cat "$tmp/err")"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/x.gcvf" --profile $j7 --calibration "$tmp/connex-cal.json" \
  --allow-calibration-materials-mismatch --quiet > /dev/null 2> "$tmp/err" || fail "forced mismatch: $(cat "$tmp/err")"
grep -q "used anyway" "$tmp/err" || fail "forced mismatch without a warning"
"$rodfab" calibrate "$src/examples/calibration/vero-tango-60C.csv" --materials VeroUltraWhite,Agilus30Black -o "$tmp/j7-cal.json" > "$tmp/out" ||
  fail "calibrate --materials"
grep -q "materials:     VeroUltraWhite (rigid), Agilus30Black (rubbery)" "$tmp/out" || fail "calibrate summary: $(cat "$tmp/out")"
"$rodfab" slice "$tmp/rod.json" -o "$tmp/y.gcvf" --profile $j7 --calibration "$tmp/j7-cal.json" --quiet > "$tmp/summary" 2> "$tmp/err" ||
  fail "matching calibration: $(cat "$tmp/err")"
! grep -q -i "warning" "$tmp/summary" "$tmp/err" || fail "a matching calibration warned"
"$rodfab" calibrate "$src/examples/calibration/vero-tango-60C.csv" --materials VeroUltraWhite > /dev/null 2>&1
[ $? -eq 2 ] || fail "calibrate --materials with one name: expected exit 2"
"$rodfab" calibrate "$src/examples/calibration/vero-tango-60C.csv" --materials VeroUltraWhite,VeroUltraWhite -o "$tmp/same.json" 2> "$tmp/err"
[ $? -eq 2 ] && grep -q "expected two different materials" "$tmp/err" && [ ! -e "$tmp/same.json" ] ||
  fail "calibrate --materials naming one material twice: expected exit 2: $(cat "$tmp/err")"
# The Connex3 with its own calibration: no warning.
"$rodfab" slice "$tmp/rod.json" -o "$tmp/c3.zip" --quiet > "$tmp/summary" 2> "$tmp/err" || fail "connex3 slice"
! grep -q -i "warning" "$tmp/summary" "$tmp/err" || fail "connex3 with its calibration warned: $(cat "$tmp/err")"

# Coupons for the J750: how a lab replaces the stand-in calibration.
"$rodfab" coupons -o "$tmp/coupons.gcvf" --profile $j7 --fractions 0,0.5,1 --size 3x1x0.2 --quiet > /dev/null 2> "$tmp/err" ||
  fail "coupons --profile $j7: $(cat "$tmp/err")"
decode "$tmp/coupons.gcvf" --expect-thickness-nm 27000 > /dev/null || fail "decoder refused the coupons job"
"$rodfab" inspect "$tmp/coupons.gcvf" > /dev/null 2>&1 || fail "inspect coupons"

# Voxelize takes the profile's voxel (and its print mode); --voxel-size replaces it, not both.
"$rodfab" voxelize "$tmp/rod.json" -o "$tmp/rod.vdb" --profile $j7 --print-mode high-mix --json > "$tmp/vox" || fail "voxelize --profile"
python3 -c "import json; j=json.load(open('$tmp/vox')); assert j['voxel_size_mm'] == [0.0423, 0.0846, 0.014], j['voxel_size_mm']" ||
  fail "voxelize did not use the high-mix voxel"
"$rodfab" voxelize "$tmp/rod.json" -o "$tmp/rod-c3.vdb" --json > "$tmp/vox" || fail "voxelize default"
python3 -c "import json; j=json.load(open('$tmp/vox')); assert j['voxel_size_mm'] == [0.0423, 0.0846, 0.03], j" || fail "default voxel"
"$rodfab" voxelize "$tmp/rod.json" -o "$tmp/rod2.vdb" --profile $j7 --voxel-size 0.1,0.1,0.1 > /dev/null 2>&1
[ $? -eq 2 ] || fail "--voxel-size with --profile: expected exit 2"

# Inspect finds a foreign colour, a wrong VoxelCount and broken XML (the manifest's checksums updated).
tamper() {  # NAME PYTHON (edits `files`: name -> bytes) PATTERN
  python3 - "$tmp/rod.gcvf" "$tmp/$1.gcvf" "$2" <<'PY'
import hashlib, json, sys, zipfile, zlib, struct
files = {i.filename: zipfile.ZipFile(sys.argv[1]).read(i) for i in zipfile.ZipFile(sys.argv[1]).infolist()}
def png_rgba(w, h, pixel):
    raw = b"".join(b"\0" + bytes(pixel) * w for _ in range(h))
    def chunk(k, b): return struct.pack(">I", len(b)) + k + b + struct.pack(">I", zlib.crc32(k + b))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)) +
            chunk(b"pHYs", struct.pack(">IIB", 23622, 11811, 1)) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
m = json.loads(files["manifest.json"])
exec(sys.argv[3])
for n, d in files.items():
    if n in m["files"]: m["files"][n] = {"bytes": len(d), "sha256": hashlib.sha256(d).hexdigest()}
files["manifest.json"] = json.dumps(m).encode()
with zipfile.ZipFile(sys.argv[2], "w") as z:
    for n, d in files.items(): z.writestr(n, d)
PY
  "$rodfab" inspect "$tmp/$1.gcvf" > "$tmp/err" 2>&1
  local got=$?
  [ $got -eq 1 ] || fail "inspect $1: exit $got, expected 1 ($(cat "$tmp/err"))"
  grep -q -- "$3" "$tmp/err" || fail "inspect $1: expected '$3' in: $(cat "$tmp/err")"
}
tamper foreign 'files["layer_0.png"] = png_rgba(m["image"]["width"], m["image"]["height"], (1, 2, 3, 255))' \
  "layer_0.png: .* pixels have a colour that is not in the material list (first: 1 2 3 255 at column 0, row 0)"
tamper count 'files["ConfigFile.xml"] = files["ConfigFile.xml"].replace(b"<VoxelCount>", b"<VoxelCount>1", 1)' \
  "ConfigFile.xml: GCVF/MaterialList/Material\[1\]/VoxelCount: expected"
tamper broken 'files["ConfigFile.xml"] = files["ConfigFile.xml"].replace(b"</GCVF>", b"")' "ConfigFile.xml: not well-formed XML"
tamper thickness 'files["ConfigFile.xml"] = files["ConfigFile.xml"].replace(b">27000<", b">14000<")' \
  'SliceThicknessNanoMeter: expected "27000", found "14000"'
tamper padded 'files["layer_00.png"] = files["layer_0.png"]' "layer_00.png: unexpected entry"
echo "PASS"
