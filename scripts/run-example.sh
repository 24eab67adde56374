#!/usr/bin/env bash
# Installs dependencies, builds rodfab and runs the main job on a bundled example design.
# Usage: scripts/run-example.sh [DESIGN.json]   (default: examples/unfolding-box.json)
set -euo pipefail
cd "$(dirname "$0")/.."
design=${1:-examples/unfolding-box.json}
bash scripts/build.sh
./build/slicer/rodfab validate "$design"
