#!/usr/bin/env bash
# Builds the Google Benchmark programs (Release) and runs them, one workload per process so that each
# reports its own peak resident memory. Results: build/bench-results/*.json (Google Benchmark JSON).
#   scripts/bench.sh [all|slice|voxel|dither|printer|calibration]
# The 6-gigavoxel runs (slice, voxel) take a few minutes; nothing else should load the machine.
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:-all}
bash scripts/build.sh > /dev/null
out=build/bench-results
mkdir -p "$out"
run() {  # NAME PROGRAM FILTER
  echo "== $1"
  "./build/bench/$2" --benchmark_filter="$3" --benchmark_out="$out/$1.json" --benchmark_out_format=json
}
case $what in all|slice)
  run slice-spring6g-1thread bench_slice '^slice/spring6g/1/'
  run slice-spring6g-2threads bench_slice '^slice/spring6g/2/'
  run slice-dense bench_slice '^slice/dense/' ;;
esac
case $what in all|voxel)
  for f in $(./build/bench/bench_voxel --benchmark_list_tests | sed 's|/.*||' | sort -u); do
    run "voxel-$f" bench_voxel "^$f/"
  done ;;
esac
case $what in all|dither) run dither bench_dither '.' ;; esac
case $what in all|printer) run printer-profiles bench_printer_profiles '.' ;; esac
case $what in all|calibration) run calibration bench_calibration '.' ;; esac
echo "results in $out/"
