#!/usr/bin/env bash
# rodfab dither-report from the command line: the report, its JSON, exit codes and messages.
#   dither_report.sh RODFAB SOURCE_DIR
set -u
rodfab=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

small=(--block 32x16x30 --fractions 0.2,0.7 --rod-length 2)
"$rodfab" dither-report "${small[@]}" > "$tmp/out" 2>&1 || fail "report failed: $(cat "$tmp/out")"
for m in white blue error-diffusion; do
  [ "$(grep -c "^$m " "$tmp/out")" -eq 3 ] || fail "expected 3 rows (2 blocks, 1 rod) for $m: $(cat "$tmp/out")"
done
grep -q "rod x 0.30" "$tmp/out" || fail "no rod row"

"$rodfab" dither-report "${small[@]}" --dither blue --json > "$tmp/json" || fail "--json"
grep -q '"ditherer": "blue"' "$tmp/json" || fail "--json lacks the ditherer"
grep -q '"lowpass_rms_100um"' "$tmp/json" || fail "--json lacks the low-pass error"
grep -q '"white"' "$tmp/json" && fail "--dither blue reported white too"
# The old spelling --ditherer still works (not listed by --help); "random" is white, as in slice and coupons.
"$rodfab" dither-report "${small[@]}" --ditherer blue --json > "$tmp/json2" || fail "--ditherer"
cmp -s <(grep -v mvoxels "$tmp/json") <(grep -v mvoxels "$tmp/json2") || fail "--ditherer blue differs from --dither blue"
"$rodfab" dither-report --help | grep -q -- "--ditherer" && fail "--help lists the old spelling --ditherer"
"$rodfab" dither-report "${small[@]}" --dither random --json > "$tmp/json3" || fail "--dither random"
grep -q '"ditherer": "white"' "$tmp/json3" || fail "--dither random is not white"

# The progression of the README (0.1,0.2,...,0.9) is the nine fractions written out.
"$rodfab" dither-report --block 8x8x8 --rod-length 1 --dither white --fractions 0.1,0.2,...,0.9 --json > "$tmp/a" || fail "0.1,0.2,...,0.9"
"$rodfab" dither-report --block 8x8x8 --rod-length 1 --dither white --fractions 0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9 --json > "$tmp/b" ||
  fail "0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9"
cmp -s <(grep -v mvoxels "$tmp/a") <(grep -v mvoxels "$tmp/b") || fail "0.1,0.2,...,0.9 is not the nine fractions"
[ "$(grep -c '"region": "block' "$tmp/a")" -eq 9 ] || fail "0.1,0.2,...,0.9: expected 9 blocks"
"$rodfab" dither-report --fractions 0.1,...,0.9 2> "$tmp/err"
[ $? -eq 2 ] && grep -q -- "--fractions: '...' needs two values before it" "$tmp/err" || fail "0.1,...,0.9: no step, expected usage exit 2"
"$rodfab" dither-report --fractions 0.5,0.5 2> "$tmp/err"
[ $? -eq 2 ] && grep -q "listed twice" "$tmp/err" || fail "a fraction twice: expected usage exit 2"

"$rodfab" dither-report --dither floyd 2> "$tmp/err"
[ $? -eq 2 ] || fail "unknown ditherer: expected usage exit 2"
grep -q "unknown ditherer 'floyd'" "$tmp/err" || fail "unknown ditherer not named"
"$rodfab" dither-report --fractions 0.2,1.4 2> "$tmp/err"
[ $? -eq 2 ] || fail "fraction 1.4: expected usage exit 2"
grep -q -- "--fractions" "$tmp/err" || fail "bad fraction not named"
"$rodfab" dither-report --block 3x0x2 2> "$tmp/err"
[ $? -eq 2 ] || fail "empty block: expected usage exit 2"
grep -q -- "--block: expected XxYxZ in voxels" "$tmp/err" || fail "--block message does not say voxels: $(cat "$tmp/err")"

printf 'not a mask' > "$tmp/bad.rfbn"
"$rodfab" dither-report "${small[@]}" --mask "$tmp/bad.rfbn" 2> "$tmp/err"
[ $? -eq 1 ] || fail "bad mask file: expected exit 1"
grep -q "bad.rfbn: magic" "$tmp/err" || fail "bad mask file not named: $(cat "$tmp/err")"

"$rodfab" dither-report --help | grep -q "usage: rodfab dither-report" || fail "--help"
echo "cli dither-report: ok"
