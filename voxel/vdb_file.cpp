#include "voxel/vdb_file.hpp"

#include <openvdb/io/File.h>

#include <unistd.h>

#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <system_error>

namespace rodfab::voxel {

namespace {

void initializeOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

}  // namespace

void writeGridFile(const std::string& path, const openvdb::GridBase& grid, const openvdb::MetaMap& fileMetadata) {
  initializeOpenVdb();
  namespace fs = std::filesystem;
  const fs::path target(path);
  fs::path temporary = target;
  temporary += ".tmp-" + std::to_string(::getpid());
  try {
    openvdb::io::File file(temporary.string());
    openvdb::GridCPtrVec grids{grid.copyGrid()};
    file.write(grids, fileMetadata);
    file.close();
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error(path + ": cannot write the grid: " + e.what());
  }
  std::error_code ec;
  fs::rename(temporary, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error(path + ": cannot move the finished file into place: " + ec.message());
  }
}

openvdb::FloatGrid::Ptr readFloatGrid(const std::string& path, const std::string& gridName) {
  initializeOpenVdb();
  openvdb::GridBase::Ptr base;
  try {
    openvdb::io::File file(path);
    file.open();
    if (!file.hasGrid(gridName)) throw std::runtime_error("no grid named '" + gridName + "'");
    base = file.readGrid(gridName);
    file.close();
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot read grid '" + gridName + "': " + e.what());
  }
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
  if (!grid) throw std::runtime_error(path + ": grid '" + gridName + "' holds " + base->valueType() + ", expected float");
  return grid;
}

}  // namespace rodfab::voxel
