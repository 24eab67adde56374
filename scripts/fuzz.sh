#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (+ ASan/UBSan) and runs one or all of them.
#   scripts/fuzz.sh [TARGET|all] [SECONDS]      e.g. scripts/fuzz.sh design_reader 600
# The corpus lives in tests/fuzz/corpus/<target>/ (kept in the repository): each run starts from it and
# replaces it with the minimized union of old and new inputs. Crashes go to build-fuzz/crashes/.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${1:-all}
seconds=${2:-600}
bash scripts/install-deps.sh
command -v clang++ >/dev/null || { echo "fuzz.sh: needs clang++ (apt-get install clang libclang-rt-14-dev)" >&2; exit 1; }
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
      -DRODFAB_FUZZ=ON -DRODFAB_BUILD_TESTS=OFF -DRODFAB_BUILD_BENCH=OFF >/dev/null
targets=()
if [ "$target" = all ]; then
  for f in tests/fuzz/fuzz_*.cpp; do n=$(basename "$f" .cpp); targets+=("${n#fuzz_}"); done
else
  targets=("$target")
fi
mkdir -p build-fuzz/crashes
for t in "${targets[@]}"; do
  cmake --build build-fuzz -j"$(nproc)" --target "fuzz_$t"
  corpus=tests/fuzz/corpus/$t
  work=build-fuzz/corpus/$t
  fuzzer=./build-fuzz/tests/fuzz/fuzz_$t
  mkdir -p "$corpus" "$work"
  cp -n "$corpus"/* "$work"/ 2>/dev/null || true
  seeds=()
  [ -d "tests/fuzz/seeds/$t" ] && seeds=("tests/fuzz/seeds/$t")
  echo "fuzzing $t for $seconds s (corpus $corpus)"
  "$fuzzer" "$work" "${seeds[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
      -print_final_stats=1 -artifact_prefix=build-fuzz/crashes/"$t"- -detect_leaks=1
  # Keep only the inputs that add coverage.
  rm -rf "$corpus.new" && mkdir -p "$corpus.new"
  if [ "$t" = inspect ]; then
    # Its inputs are whole jobs of a few KB: keep the inputs that add the most coverage edges per byte,
    # within 300 KB (scripts/corpus_budget.py prints the share of edges kept).
    rm -rf build-fuzz/merged && mkdir -p build-fuzz/merged
    "$fuzzer" -merge=1 -use_counters=0 -merge_control_file="build-fuzz/$t.merge" build-fuzz/merged "$work" "${seeds[@]}" >/dev/null 2>&1
    python3 scripts/corpus_budget.py "build-fuzz/$t.merge" 300000 "$corpus.new" "tests/fuzz/seeds/$t"
  else
    "$fuzzer" -merge=1 "$corpus.new" "$work" "${seeds[@]}" >/dev/null 2>&1
  fi
  rm -rf "$corpus" && mv "$corpus.new" "$corpus"
  echo "$t: corpus of $(ls "$corpus" | wc -l) inputs in $corpus"
done
