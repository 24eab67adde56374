#!/usr/bin/env bash
# Fails when a library defines an out-of-line function taking or returning a GCC vector of 32 bytes
# or more (voxel/raster_clips.hpp's Double4, Mask4, Owner4; materials/fraction_map.cpp's Lanes<8>).
# Code compiled for AVX2 or AVX-512 (target_clones, target("avx2")) passes such vectors in ymm/zmm
# registers, baseline code in memory, so an out-of-line copy shared by both reads garbage in one of
# them (see raster_clips.hpp): every such helper must be inlined (always_inline). 16-byte vectors
# (Eigen's packets) travel in xmm registers either way and are not flagged.
# Usage: check_vector_abi.sh LIBRARY...
set -euo pipefail
status=0
for lib in "$@"; do
  if found=$(nm -C --defined-only "$lib" | grep -E '(double|long) __vector\((4|8)\)|(float|int) __vector\((8|16)\)|short __vector\((16|32)\)|char __vector\((32|64)\)'); then
    echo "$lib: out-of-line functions with 32-byte vector arguments or results:" >&2
    echo "$found" >&2
    status=1
  fi
done
exit $status
