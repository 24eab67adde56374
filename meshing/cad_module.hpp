// Internal to meshing/: the entry point of the CAD module (librodfab_cad, cad_rods.cpp), which
// rodsFromCad (cad_module.cpp) loads on its first call, so that only rods-from-cad pays for
// OpenCASCADE's libraries (meshing/README.md, "The CAD module").
#pragma once

#include "meshing/meshing.hpp"

namespace rodfab::meshing::detail {

// What the module does: rodsFromCad's contract (meshing.hpp).
using CadReader = CadRods (*)(const std::filesystem::path& cadFile, const CadRodOptions& options);

}  // namespace rodfab::meshing::detail

// The module's one exported symbol (C linkage, so dlsym finds it by this name): its CadReader.
extern "C" rodfab::meshing::detail::CadReader rodfab_cad_reader();
inline constexpr const char* kCadReaderSymbol = "rodfab_cad_reader";
