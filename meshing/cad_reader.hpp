// Internal to meshing/: the CAD reader process. rodsFromCad (cad_process.cpp) runs the reading in a
// child process, the helper executable rodfab-cad-reader (cad_reader_main.cpp, with OpenCASCADE), found
// beside librodfab_meshing in the build tree and when installed (meshing/README.md, "The CAD reader
// process"). Why a process: OpenCASCADE's readers trust their input (a truncated IGES file is a
// SIGSEGV); in a child, whatever they do to a hostile file ends as a clear error of rods-from-cad, and
// only that command loads OpenCASCADE's 18 libraries.
#pragma once

#include "geometry/design_reader.hpp"
#include "meshing/meshing.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace rodfab::meshing::detail {

// What the helper is asked: the file, the options and the memory budget (bytes) it works under; and
// the process that asks (the helper stops at once when its parent is another: rodfab already gone).
struct CadReaderRequest {
  std::filesystem::path file;
  CadRodOptions options;
  std::uint64_t memoryBudget = 0;
  long parentProcess = 0;
};

// The helper's command line after its name, and back (exact: doubles as hexadecimal floats).
// fromReaderArguments throws std::invalid_argument on anything else.
std::vector<std::string> readerArguments(const CadReaderRequest& request);
CadReaderRequest fromReaderArguments(const std::vector<std::string>& arguments);

// What the helper found: the design (a document as geometry::designToJson makes one) and the report.
// Its rods are checked but not kept: the caller builds them once, parsing the design.
struct CadDesign {
  nlohmann::ordered_json design;
  CadRodReport report;
};

// The helper's answer, written to file descriptor kResultDescriptor: one JSON document, either
// {"design": DESIGN, "report": {...}} or {"error": MESSAGE} (MESSAGE without the file's name). Parsed
// back by rodsFromCad through geometry::parseDesign, as `rodfab validate` reads designs.
inline constexpr int kResultDescriptor = 3;
std::string resultJson(CadDesign design);
std::string errorJson(const std::string& message);

// The reading itself (cad_rods.cpp, in the helper): rodsFromCad's contract (meshing.hpp), in-process,
// after rodsFromCadThrough's checks of the options and the file (checkCadFile). Every rod is built
// once to check it (both cores, one rod a thread at a time) and let go.
CadDesign readCadDesign(const std::filesystem::path& cadFile, const CadRodOptions& options);

// Format, size and memory of the file, before any reader sees it (in the calling process); the memory
// needed depends on whether the caller keeps the rods (rodsFromCad) or writes the design (writeDesignFromCad).
void checkCadFile(const std::filesystem::path& file, geometry::RodsKept kept);

// rodsFromCad and writeDesignFromCad with the helper at `helper` (tests give stand-ins that crash, hang or lie).
CadRods rodsFromCadThrough(const std::filesystem::path& helper, const std::filesystem::path& cadFile,
                           const CadRodOptions& options);
CadDesignWritten writeDesignFromCadThrough(const std::filesystem::path& helper, const std::filesystem::path& cadFile,
                                           const CadRodOptions& options, const std::filesystem::path& designFile,
                                           const std::string& description);

}  // namespace rodfab::meshing::detail
