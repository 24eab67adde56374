// requireValidDesign (mesh.hpp): what rods-from-mesh and rods-from-cad check before writing.
#include "common/located_issues.hpp"
#include "geometry/design_file.hpp"
#include "meshing/mesh.hpp"

#include <nlohmann/json.hpp>

#include <cstdlib>

namespace rodfab::meshing {

void requireValidDesign(const geometry::RodStructure& structure, const std::filesystem::path& file,
                        const std::function<std::string(std::size_t)>& rodName) {
  try {
    geometry::summarizeDesignDocument(geometry::designToJson(structure), file.string());
  } catch (const geometry::DesignError& e) {
    const geometry::DesignIssue& issue = e.issues().front();
    std::string where = issue.path;
    if (issue.path.starts_with("rods[")) {
      const std::size_t rod = std::strtoull(issue.path.c_str() + 5, nullptr, 10);
      if (rod < structure.rods.size()) where = rodName(rod) + ", as " + issue.path;
    }
    // The cut line of a long list (common::listIssue) is not a problem of its own.
    const std::size_t more = common::listedIssueCount(e.issues()) - 1;
    const std::string others = common::issueListCut(e.issues()) ? " (and more than " + std::to_string(more) + " other problems)"
                               : more ? " (and " + std::to_string(more) + " more problems)"
                                      : "";
    throw MeshError(file, where + ": " + issue.message + others + "; the design would not be valid");
  }
}

}  // namespace rodfab::meshing
