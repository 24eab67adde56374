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

"$rodfab" dither-report "${small[@]}" --ditherer blue --json > "$tmp/json" || fail "--json"
grep -q '"ditherer": "blue"' "$tmp/json" || fail "--json lacks the ditherer"
grep -q '"lowpass_rms_100um"' "$tmp/json" || fail "--json lacks the low-pass error"
grep -q '"white"' "$tmp/json" && fail "--ditherer blue reported white too"

"$rodfab" dither-report --ditherer floyd 2> "$tmp/err"
[ $? -eq 2 ] || fail "unknown ditherer: expected usage exit 2"
grep -q "unknown ditherer 'floyd'" "$tmp/err" || fail "unknown ditherer not named"
"$rodfab" dither-report --fractions 0.2,1.4 2> "$tmp/err"
[ $? -eq 2 ] || fail "fraction 1.4: expected usage exit 2"
grep -q -- "--fractions" "$tmp/err" || fail "bad fraction not named"
"$rodfab" dither-report --block 3x0x2 2> /dev/null
[ $? -eq 2 ] || fail "empty block: expected usage exit 2"

printf 'not a mask' > "$tmp/bad.rfbn"
"$rodfab" dither-report "${small[@]}" --mask "$tmp/bad.rfbn" 2> "$tmp/err"
[ $? -eq 1 ] || fail "bad mask file: expected exit 1"
grep -q "bad.rfbn: magic" "$tmp/err" || fail "bad mask file not named: $(cat "$tmp/err")"

"$rodfab" dither-report --help | grep -q "usage: rodfab dither-report" || fail "--help"
echo "cli dither-report: ok"
