#!/usr/bin/env bash
# Installs every Debian 12 package rodfab needs to build, test and benchmark.
# Idempotent: does nothing (and prints nothing) when everything is already installed.
set -euo pipefail

packages=(
  cmake g++ make pkg-config
  libeigen3-dev
  libopenvdb-dev libopenvdb-tools libboost-iostreams-dev   # FindOpenVDB needs Boost.Iostreams
  libtbb-dev
  librandom123-dev                                           # counter-based random numbers (dithering)
  libpng-dev
  libisal-dev                                                # igzip: deflate of the layer images (printer_profiles/deflate.cpp)
  libxml2-dev                                                # reading GrabCAD Voxel Print ConfigFile.xml (inspect)
  libzip-dev zipcmp zipmerge ziptool                         # libzip's CMake config refers to these
  libboost-program-options-dev
  catch2
  libbenchmark-dev
  nlohmann-json3-dev
  libcairo2-dev                                              # calibration plots, previews
  libssl-dev                                                 # SHA-256 checksums (libcrypto)
  libxxhash-dev xxhash                                       # XXH3-128 job file checksums; xxhsum checks them in tests
  libsuitesparse-dev                                         # KLU: the mechanics solver's sparse LU
  liblbfgspp-dev                                             # L-BFGS-B for rodfab optimize (header-only)
  libnlopt-cxx-dev                                           # MMA / CCSAQ, compared in bench_optimize
  libcgal-dev                                                # meshing: mesh I/O, simplification, AABB trees
  libopenmesh-dev                                            # bench_meshing: OpenMesh's decimater, compared
  libocct-data-exchange-dev libocct-modeling-algorithms-dev libocct-modeling-data-dev libocct-foundation-dev  # rods-from-cad
  chromium                                                   # renders the job report in tests (cli_report)
  dpkg-dev fakeroot                                          # cpack -G DEB: dpkg-shlibdeps finds the package's dependencies
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

as_root=()
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
  as_root=(sudo)
fi
echo "install-deps: installing ${missing[*]}" >&2
"${as_root[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
