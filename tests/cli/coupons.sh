#!/usr/bin/env bash
# rodfab coupons from the command line: a small coupon job decoded bar by bar from its PNG layers, the
# labels in its manifest, and the errors a technician sees.
#   coupons.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
[ -d "$src/printer_profiles" ] || fail "no source folder at $src"

"$rodfab" coupons --fractions 0,0.3,1 --dither blue --seed 7 --size 6x2x0.3 --format dir --image-format png --quiet \
  -o "$tmp/job" > "$tmp/out" 2>&1 || fail "coupons: $(cat "$tmp/out")"
grep -q "^coupons: *3 bars of" "$tmp/out" || fail "no bar summary: $(cat "$tmp/out")"
grep -q "dithering: *blue, seed 7" "$tmp/out" || fail "no dithering line: $(cat "$tmp/out")"
"$rodfab" inspect "$tmp/job" > "$tmp/inspect" 2>&1 || fail "inspect of the coupon job: $(cat "$tmp/inspect")"

# Decode every layer image and count each bar's Vero and Tango pixels; compare with the labels.
python3 - "$tmp/job" "$tmp/out" <<'PY' || fail "coupon job content"
import json, os, struct, sys, zlib

job = sys.argv[1]
m = json.load(open(os.path.join(job, "manifest.json")))

def png_rows(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR": ihdr = struct.unpack(">IIBBBBB", body)
        if kind == b"IDAT": idat += body
        pos += 12 + n
    w, h, depth, colour, _, _, interlace = ihdr
    assert (depth, colour, interlace) == (1, 0, 0), (path, ihdr)
    raw, stride, rows, prev = zlib.decompress(idat), (w + 7) // 8, [], bytearray((w + 7) // 8)
    for r in range(h):
        f, line = raw[r * (stride + 1)], bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
        for x in range(stride):
            a, b, c = line[x - 1] if x else 0, prev[x], prev[x - 1] if x else 0
            p = a + b - c
            pred = [0, a, b, (a + b) // 2,
                    a if abs(p - a) <= abs(p - b) and abs(p - a) <= abs(p - c) else b if abs(p - b) <= abs(p - c) else c][f]
            line[x] = (line[x] + pred) & 0xFF
        rows.append(bytes(line))
        prev = line
    return w, h, rows

def ones(rows, c0, c1, r0, r1):  # set bits in columns [c0, c1) of rows [r0, r1)
    return sum((rows[r][c >> 3] >> (7 - (c & 7))) & 1 for r in range(r0, r1) for c in range(c0, c1))

vx, vy, vz = m["profile"]["voxel_size_mm"]
frame, coupons = m["frame"], m["metadata"]["coupons"]
bars = coupons["bars"]
assert m["dithering"]["ditherer"] == "blue" and coupons["ditherer"] == "blue", coupons["ditherer"]
assert [b["vero_fraction"] for b in bars] == [0, 0.3, 1], [b["vero_fraction"] for b in bars]
assert [b["index"] for b in bars] == [0, 1, 2]
assert all(b["ditherer"] == "blue" and b["seed"] == 7 for b in bars)
size = coupons["size_voxels"]
for asked, n, v in zip([6, 2, 0.3], size, [vx, vy, vz]):
    assert abs(n - asked / v) <= 1, (asked, n, v)
vero_name, tango_name = [x["name"] for x in m["materials"] if x["role"] in ("rigid", "rubbery")]
layers = {l["layer"]: l["files"] for l in m["layers"]}
assert m["layer_count"] == size[2] == len(layers)

boxes = []
for b in bars:
    lo, hi = b["bounds_voxels"]["min"], b["bounds_voxels"]["max"]
    assert [h - l + 1 for l, h in zip(lo, hi)] == size, (lo, hi, size)
    assert b["voxels"] == size[0] * size[1] * size[2]
    # Positions in mm agree with the voxel bounds and with the manifest's pixel-to-mm frame.
    for a, v in enumerate([vx, vy, vz]):
        assert abs(b["position_mm"][a] - lo[a] * v) < 1e-9 and abs(b["bounds_mm"]["max"][a] - (hi[a] + 1) * v) < 1e-9
        assert abs(frame["origin_mm"][a] + lo[a] * v - v / 2 - b["position_mm"][a]) < 1e-9
    boxes.append((lo, hi))
for (a0, a1), (b0, b1) in zip(boxes, boxes[1:]):  # one row along x, 5 mm apart
    assert a0[1] == b0[1] and abs((b0[0] - a1[0] - 1) * vx - 5) < vx, (a1, b0)

counts = [[0, 0, 0] for _ in bars]  # vero, tango, both
total_vero = total_tango = 0
w = h = None
for layer, files in layers.items():
    w, h, vero = png_rows(os.path.join(job, files[vero_name]))
    _, _, tango = png_rows(os.path.join(job, files[tango_name]))
    assert (w, h) == (m["image"]["width"], m["image"]["height"])
    total_vero += ones(vero, 0, w, 0, h)
    total_tango += ones(tango, 0, w, 0, h)
    k = frame["first_layer_k"] + layer
    for n, (lo, hi) in enumerate(boxes):
        if not lo[2] <= k <= hi[2]: continue
        c0, c1 = lo[0] - frame["first_column_i"], hi[0] - frame["first_column_i"] + 1
        r0, r1 = frame["top_row_j"] - hi[1], frame["top_row_j"] - lo[1] + 1
        counts[n][0] += ones(vero, c0, c1, r0, r1)
        counts[n][1] += ones(tango, c0, c1, r0, r1)
per_bar = size[0] * size[1] * size[2]
for n, (b, (v, t, _)) in enumerate(zip(bars, counts)):
    assert v + t == per_bar, (n, v, t, per_bar)  # every voxel of the bar, one material each
    assert b["vero_voxels"] == v, (n, b["vero_voxels"], v)
share = [v / per_bar for v, _, _ in counts]
assert share[0] == 0 and share[2] == 1, share
assert abs(share[1] - 0.3) <= 0.03, share
assert (total_vero, total_tango) == (sum(c[0] for c in counts), sum(c[1] for c in counts)), "pixels outside the bars"
summary = open(sys.argv[2]).read()
assert "%.4f" % share[1] in summary, summary
PY

# A progression and the published pipeline's name for white noise; a zip that inspect passes.
"$rodfab" coupons --fractions 0,0.25,...,1 --dither random --size 6x2x0.3 --quiet --json -o "$tmp/c.zip" > "$tmp/json" ||
  fail "coupons --json: $(cat "$tmp/json")"
python3 - "$tmp/json" <<'PY' || fail "--json content"
import json, sys
j = json.load(open(sys.argv[1]))
assert [b["vero_fraction"] for b in j["bars"]] == [0, 0.25, 0.5, 0.75, 1], j["bars"]
assert j["ditherer"] == "white" and all(b["ditherer"] == "white" for b in j["bars"])
assert j["rows"] == 1 and j["per_row"] == 5
PY
"$rodfab" inspect "$tmp/c.zip" > /dev/null 2>&1 || fail "inspect of the zip"

# Bad command-line values exit 2 and name the value; nothing is written.
expect() {  # expect CODE PATTERN ARGS...
  local code=$1 pattern=$2; shift 2
  "$rodfab" coupons "$@" > /dev/null 2> "$tmp/err"
  local got=$?
  [ $got -eq "$code" ] || fail "coupons $*: exit $got, expected $code: $(cat "$tmp/err")"
  grep -q -- "$pattern" "$tmp/err" || fail "coupons $*: message lacks '$pattern': $(cat "$tmp/err")"
}
expect 2 "--fractions: 1.2 is not a Vero fraction in \[0, 1\]" --fractions 0,1.2 -o "$tmp/x.zip"
expect 2 "--fractions: -0.1 is not" --fractions -0.1,0.5 -o "$tmp/x.zip"
expect 2 "--fractions: 'abc' is not a number" --fractions 0,abc -o "$tmp/x.zip"
expect 2 "--fractions: 0.50 is listed twice" --fractions 0,0.5,0.50 -o "$tmp/x.zip"
expect 2 "--fractions: steps of 0.3 from 0.3 do not reach 1" --fractions 0,0.3,...,1 -o "$tmp/x.zip"
expect 2 "--fractions: expected a value, got an empty string" --fractions "" -o "$tmp/x.zip"
expect 2 "--dither: unknown ditherer 'purple'" --dither purple -o "$tmp/x.zip"
expect 2 "--size: expected LENGTHxWIDTHxHEIGHT" --size 6x2 -o "$tmp/x.zip"
expect 2 "--size: 0.01 mm along z is less than one voxel" --size 6x2x0.01 -o "$tmp/x.zip"
expect 2 "--gap: expected" --gap 0 -o "$tmp/x.zip"
expect 2 "--format: expected zip or dir" --format tar -o "$tmp/x.zip"
expect 2 "required" --fractions 0,1
# Bars that do not fit the tray exit 1 and say by how many mm.
expect 1 "too large by 109.983 mm along x" --size 600x5x1.5 -o "$tmp/x.zip"
expect 1 "mm along y" --size 300x200x0.3 --fractions 0,0.5,1 -o "$tmp/x.zip"
[ ! -e "$tmp/x.zip" ] || fail "a refused run left a job behind"

# An existing job is never replaced without --force, and stays as it was.
(cd "$tmp/job" && find . -type f | sort | xargs sha256sum) > "$tmp/before"
expect 1 "already exists" --fractions 0.5 --size 6x2x0.3 --format dir --quiet -o "$tmp/job"
(cd "$tmp/job" && find . -type f | sort | xargs sha256sum) > "$tmp/after"
cmp -s "$tmp/before" "$tmp/after" || fail "the existing job was changed"
"$rodfab" coupons --fractions 0.5 --size 6x2x0.3 --format dir --quiet --force -o "$tmp/job" > /dev/null 2>&1 || fail "--force"
grep -q '"vero_fraction": 0.5' "$tmp/job/manifest.json" || fail "--force did not replace the job"
[ -z "$(ls -A "$tmp" | grep rodfab-partial)" ] || fail "temporaries left: $(ls -A "$tmp")"

# --force replaces only rodfab jobs: a user's folder, or a coupon job with a file added, stays byte for byte.
mkdir -p "$tmp/u/mydata"
echo "measurements" > "$tmp/u/mydata/dma.csv"
cp -r "$tmp/job" "$tmp/u/job-plus"; echo "mine" > "$tmp/u/job-plus/notes.txt"
listing() { (cd "$tmp/u" && find . -printf '%p %y\n' | sort && find . -type f -exec sha256sum {} + | sort); }
before=$(listing)
expect 1 "mydata: is a folder without a rodfab job manifest.*rodfab replaces only its own jobs" --size 6x2x0.3 --quiet --force -o "$tmp/u/mydata"
expect 1 "mydata: is a folder without a rodfab job manifest" --size 6x2x0.3 --quiet --force -o "$tmp/u/mydata/"
expect 1 "'notes.txt', which is not part of that job" --size 6x2x0.3 --quiet --force --format dir -o "$tmp/u/job-plus"
[ "$(listing)" = "$before" ] || fail "a refused --force changed the folder: $(diff <(echo "$before") <(listing))"
"$rodfab" coupons --fractions 0.5 --size 6x2x0.3 --quiet --force -o "$tmp/job" > /dev/null 2>&1 || fail "a zip job over a dir job"
[ -f "$tmp/job" ] && "$rodfab" inspect "$tmp/job" > /dev/null 2>&1 || fail "the replacing zip job"

# SIGTERM mid-job: exit 143, nothing written.
mkdir "$tmp/t"
"$rodfab" coupons --fractions 0,0.5,1 --size 40x20x0.3 --threads 1 --band-layers 1 -o "$tmp/t/c.zip" > /dev/null 2> "$tmp/progress" &
pid=$!
for _ in $(seq 1 500); do grep -q "layers" "$tmp/progress" 2> /dev/null && break; sleep 0.01; done
kill -TERM $pid
wait $pid
code=$?
[ $code -eq 143 ] || fail "SIGTERM: exit $code, expected 143 ($(cat "$tmp/progress"))"
grep -q "interrupted by SIGTERM; nothing was written" "$tmp/progress" || fail "SIGTERM not reported: $(cat "$tmp/progress")"
[ -z "$(ls -A "$tmp/t")" ] || fail "SIGTERM left: $(ls -A "$tmp/t")"

# A job that passes the memory check runs within that budget (it is also the data limit): three
# 400 x 40 x 1.5 mm bars (1.33 GB resident). The estimate counted 5 bytes a band voxel for both bands'
# fractions and material, 1.1 GiB, and the job then ran out of memory at 1.2 GiB.
need=$("$rodfab" coupons --fractions 0,0.5,1 --size 400x40x1.5 --band-layers 8 --quiet -o "$tmp/big.zip" --max-memory 100M 2>&1 |
       grep -o "needs about [0-9.]* [GM]iB")
budget=$(echo "$need" | awk '{ printf "%.0fM", ($4 == "GiB" ? $3 * 1024 : $3) + 0.06 * 1024 }')  # above the rounding of the figure
[ -n "$need" ] || fail "no estimate in the refusal at 100M"
"$rodfab" coupons --fractions 0,0.5,1 --size 400x40x1.5 --band-layers 8 --quiet -o "$tmp/big.zip" --max-memory "$budget" \
  > "$tmp/out" 2>&1 || fail "a coupon job within its own estimate ($need, budget $budget) failed: $(tail -2 "$tmp/out")"
rm -f "$tmp/big.zip"

"$rodfab" coupons --help | grep -q "usage: rodfab coupons" || fail "--help"
"$rodfab" --help | grep -q "coupons" || fail "coupons missing from rodfab --help"
echo "coupons: ok"
