#!/usr/bin/env bash
# rodfab calibrate from the command line: the fit table, the files it writes, exit codes and messages.
#   calibrate.sh RODFAB SOURCE_DIR
set -u
rodfab=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

csv="$src/examples/calibration/vero-tango-60C.csv"
"$rodfab" calibrate "$csv" --output "$tmp/cal.json" --plot "$tmp/fit.png" > "$tmp/out" 2>&1 || fail "bundled data: $(cat "$tmp/out")"
grep -q "floor:         8 MPa -> 30.0000 % Vero" "$tmp/out" || fail "no floor line: $(cat "$tmp/out")"
grep -q "model:         pchip" "$tmp/out" || fail "pchip is not the default model"
grep -q '"format": "rodfab.calibration/1"' "$tmp/cal.json" || fail "calibration file lacks its format tag"
grep -q "\"sha256\": \"$(sha256sum "$csv" | cut -d' ' -f1)\"" "$tmp/cal.json" || fail "checksum is not sha256sum's"
[ "$(head -c 8 "$tmp/fit.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "plot is not a PNG"
ls "$tmp" | grep -q '\.tmp$' && fail "a temporary file was left behind"

"$rodfab" calibrate "$csv" --model lichtenecker > "$tmp/out" || fail "lichtenecker"
grep -q "exponent:      a = 0.23" "$tmp/out" || fail "lichtenecker exponent: $(cat "$tmp/out")"
"$rodfab" calibrate "$csv" --model log-power > "$tmp/out" || fail "log-power"
grep -q "exponent:      n = 0.63" "$tmp/out" || fail "log-power exponent: $(cat "$tmp/out")"

# Bad rows: each reported with its line, exit 1, nothing written.
printf 'vero_fraction,modulus_mpa\n0,0.5\nhalf,3\n1.5,8\n1,190\n' > "$tmp/bad.csv"
"$rodfab" calibrate "$tmp/bad.csv" --output "$tmp/bad.json" > "$tmp/out" 2> "$tmp/err"
[ $? -eq 1 ] || fail "bad rows: expected exit 1"
grep -q "bad.csv: line 3: vero_fraction: expected a Vero fraction from 0 to 1, got 'half'" "$tmp/err" || fail "line 3 not reported: $(cat "$tmp/err")"
grep -q "bad.csv: line 4: vero_fraction: expected a fraction from 0 to 1, got '1.5'" "$tmp/err" || fail "line 4 not reported"
grep -q "2 errors; nothing fitted" "$tmp/err" || fail "no error count"
[ ! -e "$tmp/bad.json" ] || fail "a calibration was written from bad data"

# 300 bad rows: 100 listed, then the cut line, which the count does not take for an error.
{ echo vero_fraction,modulus_mpa; for i in $(seq 1 300); do echo "half,$i"; done; } > "$tmp/many.csv"
"$rodfab" calibrate "$tmp/many.csv" > /dev/null 2> "$tmp/err"
[ $? -eq 1 ] || fail "300 bad rows: expected exit 1"
[ "$(grep -c "got 'half'" "$tmp/err")" -eq 100 ] || fail "300 bad rows: not 100 listed"
[ "$(tail -1 "$tmp/err")" = "$tmp/many.csv: 100 errors shown, more were found; nothing fitted" ] ||
  fail "300 bad rows, the count: $(tail -1 "$tmp/err")"

# Non-monotone means: refused for pchip, naming the fractions.
printf 'vero_fraction,modulus_mpa\n0,0.5\n0.4,12\n0.5,11\n1,190\n' > "$tmp/dip.csv"
"$rodfab" calibrate "$tmp/dip.csv" 2> "$tmp/err" > /dev/null
[ $? -eq 1 ] || fail "non-monotone: expected exit 1"
grep -q "0.4 (12 MPa, 1 specimen, line 3) -> 0.5 (11 MPa, 1 specimen, line 4)" "$tmp/err" || fail "offending fractions not named: $(cat "$tmp/err")"
"$rodfab" calibrate "$tmp/dip.csv" --model log-power > /dev/null || fail "log-power should fit non-monotone data"

"$rodfab" calibrate "$tmp/absent.csv" 2> "$tmp/err"
[ $? -eq 1 ] || fail "missing file: expected exit 1"
grep -q "absent.csv: cannot open" "$tmp/err" || fail "missing file not named"
"$rodfab" calibrate "$csv" --floor-mpa 0.1 2> "$tmp/err" > /dev/null
[ $? -eq 1 ] || fail "floor below pure Tango: expected exit 1"
grep -q "lies outside the printable range" "$tmp/err" || fail "floor range not explained: $(cat "$tmp/err")"

"$rodfab" calibrate 2> /dev/null
[ $? -eq 2 ] || fail "no data argument: expected usage exit 2"
"$rodfab" calibrate "$csv" --model spline 2> "$tmp/err"
[ $? -eq 2 ] || fail "unknown model: expected usage exit 2"
grep -q "expected pchip, lichtenecker or log-power" "$tmp/err" || fail "unknown model not explained"
"$rodfab" calibrate "$csv" --floor-mpa -3 2> /dev/null
[ $? -eq 2 ] || fail "negative floor: expected usage exit 2"
"$rodfab" calibrate --help | grep -q "usage: rodfab calibrate" || fail "--help"

# 100 replicates at each of 21 fractions, plotted within a small budget: cairo cannot survive a failed
# allocation (its scan converter jumped through a broken jmp_buf: a segfault, the calibration file
# left behind), so the budget's data limit is lifted while a plot is drawn (common::DataLimitLifted).
awk 'BEGIN { print "vero_fraction,modulus_mpa,dither"
             for (i = 0; i <= 20; i++) for (r = 0; r < 100; r++)
               printf "%.2f,%.6g,random\n", i / 20, 0.57 * exp(i / 20 * log(2000 / 0.57)) * (1 + 0.03 * sin(r * 7.3 + i * 1.1)) }' > "$tmp/replicates.csv"
"$rodfab" calibrate "$tmp/replicates.csv" --max-memory 64M -o "$tmp/replicates.json" --plot "$tmp/replicates.png" > "$tmp/out" 2>&1
code=$?
[ $code -eq 0 ] || fail "2,100 measurements plotted in 64 MiB: exit $code: $(tail -c 300 "$tmp/out")"
[ "$(head -c 8 "$tmp/replicates.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "replicates: plot is not a PNG"
# --materials names as printer profiles give them: no escape sequence recorded to reach a terminal later.
"$rodfab" calibrate "$csv" --materials "$(printf 'Vero\033[31mX,TangoBlackPlus')" -o "$tmp/escape.json" > /dev/null 2> "$tmp/err"
[ $? -eq 2 ] || fail "--materials with an escape sequence: expected usage exit 2"
grep -q "expected material names as printer profiles give them, got 'Vero.x1b\[31mX'" "$tmp/err" || fail "--materials escape: $(cat -v "$tmp/err")"
grep -q "$(printf '\033')" "$tmp/err" && fail "--materials: a raw escape character in the message"
[ -e "$tmp/escape.json" ] && fail "--materials with an escape sequence: a calibration was written"

# Data without the optional dither column: the calibration records no ditherer (null), and slice takes
# its default or --dither (it refused the file: "dither: unknown ditherer ''").
printf 'vero_fraction,modulus_mpa\n0,0.5\n0.3,8\n0.6,40\n1,190\n' > "$tmp/no-dither.csv"
"$rodfab" calibrate "$tmp/no-dither.csv" -o "$tmp/no-dither.json" > /dev/null 2>&1 || fail "no dither column: calibrate"
grep -q '"dither": null' "$tmp/no-dither.json" || fail "no dither column: expected \"dither\": null"
for dither in "" "--dither blue"; do
  # shellcheck disable=SC2086  # $dither: no option, or an option and its value
  "$rodfab" slice "$src/examples/unfolding-box.json" -o "$tmp/no-dither${dither// /}.zip" --calibration "$tmp/no-dither.json" $dither --quiet \
    > /dev/null 2> "$tmp/err" || fail "slice with a calibration that names no ditherer ($dither): $(cat "$tmp/err")"
done
echo "calibrate CLI: all checks passed"
