// Internal to meshing/: the checks a PLY file passes before CGAL's reader sees it (mesh_io.cpp). Each
// throws MeshError naming `source` and, where there is one, the header line or the element and index.
#pragma once

#include <string>

namespace rodfab::meshing::detail {

// The header as CGAL's reader takes it (format on line 2, elements before properties, known types, vertex
// coordinates of float or double, element counts the file can hold, an end_header line), then every
// list's declared length within the bytes left after it and every item present (ASCII and both binary
// byte orders).
void checkPly(const std::string& bytes, const std::string& source);

}  // namespace rodfab::meshing::detail
