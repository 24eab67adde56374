// libFuzzer target: the design reader (rods by geometry/, the mechanics and optimize blocks by
// mechanics/) must answer every input with a design or a DesignError,
// never crash, hang or throw anything else; a design it accepts must be safe to summarize and query.
#include "geometry/geometry.hpp"
#include "mechanics/mechanics_file.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  rodfab::mechanics::Design design;
  try {
    design = rodfab::mechanics::parseDesign(text, "fuzz.json");
  } catch (const rodfab::geometry::DesignError&) {
    return 0;
  }
  const auto summary = rodfab::geometry::summarize(design);
  for (const auto& rod : design.rods) {
    const auto hit = rod.classify(summary.bounds.center());
    (void)hit;
  }
  return 0;
}
