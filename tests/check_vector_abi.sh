#!/usr/bin/env bash
# Fails when a library defines an out-of-line function taking or returning a 32-byte GCC vector
# (voxel/raster_clips.hpp's Double4, Mask4, Owner4). The rasterizer's target_clones loops pass such
# vectors in ymm registers in their avx2 clone and in memory in the baseline one, so a shared
# out-of-line copy reads garbage in one of them (see raster_clips.hpp): every such helper must be
# inlined (always_inline). Usage: check_vector_abi.sh LIBRARY...
set -euo pipefail
status=0
for lib in "$@"; do
  if found=$(nm -C --defined-only "$lib" | grep -E '(double|long) __vector\(4\)'); then
    echo "$lib: out-of-line functions with 32-byte vector arguments or results:" >&2
    echo "$found" >&2
    status=1
  fi
done
exit $status
