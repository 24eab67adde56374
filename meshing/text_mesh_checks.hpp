// Internal to meshing/: the checks text OFF and OBJ and binary STL pass before CGAL's readers see them
// (mesh_io.cpp), and the copy of a file with what those readers would misread changed. Each check
// throws MeshError naming `source` and, where there is one, the line.
#pragma once

#include <string>

namespace rodfab::meshing::detail {

inline constexpr const char* kNotFinite = "is not a finite number within the range of a double (about ±1.8e308)";

// Text OFF: keyword, counts the bytes can hold, vertex lines of 3 numbers, face lines of 3 to 1e6
// existing corners and 0, 1, 3 or 4 colours, nothing past the declared faces (see the definition).
void checkOffText(const std::string& bytes, const std::string& source);
// OBJ face lines as CGAL's reader takes them: every corner a vertex number in range, at least 3.
void checkObjFaces(const std::string& bytes, const std::string& source);
// Binary STL (not text, looksLikeTextStl): the declared triangle count matching the size (a few bytes
// of padding pass) and every coordinate finite.
void checkBinaryStlNumbers(const std::string& bytes, const std::string& source);
// The file with a UTF-8 byte order mark dropped and, in OBJ, tabs made spaces and line elements made
// comments; empty when nothing needs to change.
std::string readerCopy(const std::string& bytes, const std::string& format);

}  // namespace rodfab::meshing::detail
