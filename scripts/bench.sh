#!/usr/bin/env bash
# Builds the Google Benchmark programs (Release) and runs them, one workload per process so that each
# reports its own peak resident memory. Results: build/bench-results/*.json (Google Benchmark JSON).
#   scripts/bench.sh [all|slice|voxel|dither|printer|emit|calibration|meshing]
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
# Every benchmark class (spring, lattice, curved-lattice, dense; examples::benchmarkDesign) with each
# ditherer, whole slice with its stages (voxelize + map, dither, emit); one run per process.
case $what in all|slice)
  for t in $(./build/bench/bench_slice --benchmark_list_tests | sed 's|/iterations.*||'); do
    run "slice-$(echo "$t" | sed 's|^slice/||; s|/|-|g')threads" bench_slice "^$t/"
  done ;;
esac
# Rasterization per class: building the pieces, rasterize alone and rasterize + map (16-layer bands,
# as the slicer makes them), 1 and 2 threads; and the older spring workloads.
case $what in all|voxel)
  for f in $(./build/bench/bench_voxel --benchmark_list_tests | sed -E 's#^(class[A-Za-z]*/[a-z_]*)/.*#\1#; t; s#/.*##' | sort -u); do
    run "voxel-$(echo "$f" | tr / -)" bench_voxel "^$f/"
  done ;;
esac
case $what in all|dither) run dither bench_dither '.' ;; esac
case $what in all|printer) run printer-profiles bench_printer_profiles '.' ;; esac
# The job writer alone on every class's dithered bands (white noise, seed 7, the slicer's bands), 1 and
# 2 threads, without and with the modulus grids (classEmit, classEmitModulus); one workload per process.
case $what in all|emit)
  for t in $(./build/bench/bench_emit_class --benchmark_list_tests); do
    run "emit-$(echo "$t" | sed 's|/manual_time||; s|/iterations:1||; s|:||; s|/|-|g')" bench_emit_class "^$t\$"
  done ;;
esac
case $what in all|calibration) run calibration bench_calibration '.' ;; esac
# Rods from a 350,000-triangle mesh and the simplifiers compared; rods from CAD (200 winding splines)
# and reading their design on 1 and 2 threads; one workload per process.
case $what in all|meshing)
  for t in $(./build/bench/bench_meshing --benchmark_list_tests | sed 's|/iterations.*||; s|/real_time||' | sort -u); do
    run "meshing-$(echo "$t" | sed 's|^BM_||; s|/|-|g')" bench_meshing "^$t(/|\$)"
  done ;;
esac
echo "results in $out/"
