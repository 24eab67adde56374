// A design file with its "mechanics" and "optimize" blocks: read with full validation (the rods by
// geometry/design_reader.hpp, the blocks here, every issue of the file reported at once as
// `FILE: JSON.PATH: MESSAGE`), and written. The format is described in the README ("Design file").
#pragma once

#include "geometry/design_file.hpp"
#include "mechanics/mechanics_spec.hpp"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <string>

namespace rodfab::mechanics {

// Reads `file` and every load case's {"design": PATH} target (relative to `file`; its rods must
// carry names of this design). Throws geometry::DesignError (also for an unreadable file, path "").
Design readDesign(const std::filesystem::path& file);
// readDesign's checks (the rods, both blocks, every target design) without keeping the rods: what
// geometry::summarize says of them, in the memory of the rods being built (one a thread) rather than
// of all of them (`rodfab validate`). Throws as readDesign; and for a design with a "mechanics" block,
// checkMechanics on it (the rods read again, kept this time): MechanicsError for what a solve would refuse.
geometry::DesignSummary checkDesign(const std::filesystem::path& file);
// `sourceName` names the text in messages. Targets given as {"design": PATH} are not read (their
// LoadCase::target stays empty): readDesign reads them.
Design parseDesign(const std::string& text, const std::string& sourceName);

// The file a load case's {"design": PATH} target names: PATH as written when absolute, else PATH
// relative to the folder of `designFile` (the file the case was read from). Empty for an inline target.
// The one rule for readDesign, the optimizer's output (which rewrites PATH for its own folder) and the
// commands' input/output checks.
std::filesystem::path targetDesignFile(const LoadCase& loadCase, const std::filesystem::path& designFile);

// geometry::designToJson with the "mechanics" and "optimize" blocks (when present) after the rods.
nlohmann::ordered_json designToJson(const Design& design, const std::string& description = {});
// In the file's layout (geometry::writeDesignDocument), atomically.
void writeDesign(const Design& design, const std::filesystem::path& file, const std::string& description = {});

}  // namespace rodfab::mechanics
