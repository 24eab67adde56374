// Internal to meshing/: the checks a PLY file passes before CGAL's reader sees it (mesh_io.cpp). Each
// throws MeshError naming `source` and, where there is one, the header line or the element and index.
#pragma once

#include <string>

namespace rodfab::meshing::detail {

// Elements before properties, vertex coordinates of float or double, element counts the file can hold.
void checkPlyHeader(const std::string& bytes, const std::string& source);
// Every list's declared length within the bytes left after it (ASCII and both binary byte orders).
void checkPlyLists(const std::string& bytes, const std::string& source);

}  // namespace rodfab::meshing::detail
