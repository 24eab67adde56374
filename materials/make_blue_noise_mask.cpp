// Regenerates the bundled blue-noise threshold mask from BlueNoiseParameters::bundledMask():
//   rodfab_make_blue_noise_mask [OUTPUT]   (default: the bundled path in the source tree)
#include "materials/blue_noise_mask.hpp"

#include <chrono>
#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  using namespace rodfab::materials;
  if (argc > 2) {
    std::fprintf(stderr, "usage: rodfab_make_blue_noise_mask [OUTPUT]\n");
    return 2;
  }
  try {
    const std::filesystem::path out = argc > 1 ? std::filesystem::path(argv[1]) : BlueNoiseMask::bundledPath();
    const auto start = std::chrono::steady_clock::now();
    const BlueNoiseMask mask = BlueNoiseMask::generate(BlueNoiseParameters::bundledMask());
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    mask.save(out);
    std::printf("%s: %zu cells generated in %.2f s\n", out.string().c_str(), mask.cellCount(), seconds);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rodfab_make_blue_noise_mask: %s\n", e.what());
    return 1;
  }
  return 0;
}
