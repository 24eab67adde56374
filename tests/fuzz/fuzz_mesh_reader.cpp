// libFuzzer target: the mesh readers (CGAL's STL, OBJ, PLY and OFF readers and rodfab's checks) must
// answer every input with a checked mesh or a MeshError (or OutOfMemory when the input declares more
// than the budget), never crash, hang or throw anything else. The first byte picks the format.
#include "common/memory_budget.hpp"
#include "meshing/meshing.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* const kFormats[] = {"stl", "obj", "ply", "off"};
  const std::string format = kFormats[data[0] % 4];
  const std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    const rodfab::meshing::MeshCounts counts = rodfab::meshing::checkMeshBytes(bytes, format, "fuzz." + format);
    // A mesh that passes the checks has at least one triangle of three distinct vertices.
    if (counts.faces == 0 || counts.vertices < 3) __builtin_trap();
  } catch (const rodfab::meshing::MeshError&) {
  } catch (const rodfab::common::OutOfMemory&) {
  }
  return 0;
}
