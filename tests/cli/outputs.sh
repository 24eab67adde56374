#!/usr/bin/env bash
# Every command that writes a file, and every option that names one (--output, --plot, --render):
#  - "-" (standard output, by custom) is a usage error (exit 2) that says so, and no file "-" is made;
#  - a name too long for the hidden temporary written beside it (the name plus up to 35 bytes, within
#    the file system's 255) is refused before any work (exit 1), naming the path and the limits.
# The folder holds nothing afterwards either way.
#   outputs.sh RODFAB SOURCE_DIR
set -u
rodfab=$(realpath "$1") src=$(realpath "$2")  # absolute: the script works in its output folder
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
mkdir "$tmp/out"
cd "$tmp/out" || fail "cd"

box=$src/examples/unfolding-box.json
csv=$src/examples/calibration/vero-tango-60C.csv
mesh=$src/examples/bunny.obj
# Each command with its arguments; OUT stands for the output under test (the other outputs, if any, unset).
commands=(
  "slice $box -o OUT --quiet"
  "slice $box -o OUT --format dir --quiet"
  "coupons --fractions 0.5 --size 6x2x0.3 -o OUT --quiet"
  "voxelize $box -o OUT"
  "simulate $box -o OUT"
  "optimize $box -o OUT --max-iterations 1"
  "optimize $box -o $tmp/out/opt.json --plot OUT --max-iterations 1"
  "optimize $box -o $tmp/out/opt.json --render OUT --max-iterations 1"
  "calibrate $csv -o OUT"
  "calibrate $csv --plot OUT"
  "rods-from-mesh $mesh --faces 200 --diameter 1.5 -o OUT"
  "rods-from-cad $tmp/no-model.step --diameter 1.5 -o OUT"
)
nothing_written() {  # LABEL
  [ -z "$(ls -A "$tmp/out")" ] || fail "$1: left in the output folder: $(ls -A "$tmp/out")"
}
long=$(printf 'n%.0s' $(seq 1 250)).out  # 254 bytes: 35 more would exceed 255
for c in "${commands[@]}"; do
  option=$(echo "$c" | sed -n 's/.* \(-o\|--plot\|--render\) OUT.*/\1/p')
  [ "$option" = "-o" ] && option=--output
  # shellcheck disable=SC2086  # the words of the command, split on purpose
  "$rodfab" ${c/OUT/-} > /dev/null 2> "$tmp/err"
  code=$?
  [ $code -eq 2 ] || fail "$c with '-': exit $code, expected 2 ($(cat "$tmp/err"))"
  grep -q -- "^rodfab [a-z-]*: $option: '-' (standard output) is not supported: rodfab writes its outputs to files only; name a file (./- for a file named '-')$" "$tmp/err" ||
    fail "$c with '-': $(cat "$tmp/err")"
  nothing_written "$c with '-'"

  start=$(date +%s)
  # shellcheck disable=SC2086
  "$rodfab" ${c/OUT/$tmp/out/$long} > /dev/null 2> "$tmp/err"
  code=$?
  [ $code -eq 1 ] || fail "$c with a 254-byte name: exit $code, expected 1 ($(cat "$tmp/err"))"
  grep -q -- "$long: the file name is 254 bytes long; rodfab writes it first under a hidden name up to 35 bytes longer, and this folder's file system allows names of at most 255 bytes: use a name of at most 220 bytes" "$tmp/err" ||
    fail "$c with a 254-byte name: $(cat "$tmp/err")"
  [ $(( $(date +%s) - start )) -le 10 ] || fail "$c with a 254-byte name: refused only after $(( $(date +%s) - start )) s of work"
  nothing_written "$c with a 254-byte name"
done

# "./-" is a file named "-", written like any other.
"$rodfab" calibrate "$csv" -o ./- > /dev/null 2> "$tmp/err" || fail "calibrate -o ./-: $(cat "$tmp/err")"
[ -s "$tmp/out/-" ] || fail "calibrate -o ./- wrote no file named '-'"
rm -- "$tmp/out/-"
# A name of 220 bytes, the longest allowed, is written (its temporary fits).
ok=$(printf 'k%.0s' $(seq 1 215)).json
"$rodfab" calibrate "$csv" -o "$tmp/out/$ok" > /dev/null 2> "$tmp/err" || fail "calibrate to a 220-byte name: $(cat "$tmp/err")"
[ "$(ls -A "$tmp/out")" = "$ok" ] || fail "a 220-byte name: found $(ls -A "$tmp/out")"

# What a run killed outright (SIGKILL: no handler ran) kept of the outputs it replaced is the user's
# earlier data: the next run writing the same output names it in a warning and leaves it; a mere second
# link to the output itself (killed before its commit) is removed.
rm -f -- "$tmp/out/"*
dead=$(bash -c 'echo $$')  # a process that has ended
echo "calibration before" > "$tmp/out/.cal.json.rodfab-old-$dead-0"
"$rodfab" calibrate "$csv" -o cal.json > /dev/null 2> "$tmp/err" || fail "calibrate beside a kept copy: $(cat "$tmp/err")"
grep -q "^warning: .*/\?\.cal\.json\.rodfab-old-$dead-0 is what cal.json held before a rodfab run that was killed" "$tmp/err" ||
  fail "no warning of the kept copy: $(cat "$tmp/err")"
[ "$(cat "$tmp/out/.cal.json.rodfab-old-$dead-0")" = "calibration before" ] || fail "the kept copy was changed"
ln "$tmp/out/cal.json" "$tmp/out/.cal.json.rodfab-old-$dead-1"
"$rodfab" calibrate "$csv" -o cal.json > /dev/null 2> "$tmp/err" || fail "calibrate over its own file: $(cat "$tmp/err")"
[ -e "$tmp/out/.cal.json.rodfab-old-$dead-1" ] && fail "a second link of the output itself was left"
mkdir -p "$tmp/out/.job.rodfab-old-$dead-0/layers"
"$rodfab" slice "$box" -o job --format dir --quiet > /dev/null 2> "$tmp/err" || fail "slice beside a kept job: $(cat "$tmp/err")"
grep -q "^warning: .*\.job\.rodfab-old-$dead-0 is what job held before" "$tmp/err" || fail "no warning of the kept job: $(cat "$tmp/err")"
[ -d "$tmp/out/.job.rodfab-old-$dead-0/layers" ] || fail "the kept job was removed"
echo "outputs: ok"
