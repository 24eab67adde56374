#!/usr/bin/env bash
# The same job bytes from separate processes, two at a time and beside a busy loop, so the runs are
# preempted at different points (igzip's levels 1 and 2 gave a different, valid deflate stream for about
# one layer image in 2,000 in one process of five under such load; see printer_profiles/README.md,
# "Same bytes every run"). Each process slices the arm cast, the largest bundled job, as a BMP zip.
#   reproducible.sh RODFAB SOURCE_DIR [RUNS]
set -u
rodfab=$1 src=$2 runs=${3:-8}
tmp=$(mktemp -d)
busy() { while :; do :; done; }
busy & burner=$!
trap 'kill $burner 2>/dev/null; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
slice() { "$rodfab" slice "$src/examples/arm-cast.json" -o "$tmp/$1/arm-cast.zip" --threads "$2" --quiet > /dev/null 2> "$tmp/err$1" ||
  fail "run $1: $(cat "$tmp/err$1")"; }
for ((i = 0; i < runs; i += 2)); do
  mkdir "$tmp/$i" "$tmp/$((i + 1))"  # one folder a run: the job's name is part of its bytes
  slice $i 1 & first=$!
  slice $((i + 1)) 2 & second=$!
  ok=0
  wait $first || ok=1
  wait $second || ok=1  # both waited for: none left running while the trap removes $tmp
  [ $ok = 0 ] || exit 1
done
count=$(sha256sum "$tmp"/*/arm-cast.zip | cut -d' ' -f1 | sort -u | wc -l)
[ "$count" = 1 ] || { sha256sum "$tmp"/*/arm-cast.zip; fail "$runs runs gave $count different jobs"; }
echo "PASS: $runs processes, one job"
