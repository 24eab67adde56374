#!/usr/bin/env bash
# Installs dependencies, builds rodfab, slices a bundled example design into a print job and inspects it.
# Usage: scripts/run-example.sh [DESIGN.json]   (default: examples/unfolding-box.json)
# The job lands in build/jobs/<design>.zip.
set -euo pipefail
cd "$(dirname "$0")/.."
design=${1:-examples/unfolding-box.json}
bash scripts/build.sh
mkdir -p build/jobs
job=build/jobs/$(basename "$design" .json).zip
./build/slicer/rodfab validate "$design"
echo
./build/slicer/rodfab slice "$design" --output "$job" --force
echo
./build/slicer/rodfab inspect "$job"
