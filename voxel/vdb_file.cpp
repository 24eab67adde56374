#include "voxel/vdb_file.hpp"

#include "common/output_file.hpp"

#include <openvdb/io/File.h>

#include <unistd.h>

#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <system_error>

namespace rodfab::voxel {

namespace {

constexpr const char* kWriterKey = "rodfab_writer";

void initializeOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

}  // namespace

void writeGridFile(const std::string& path, const openvdb::GridBase& grid, const openvdb::MetaMap& fileMetadata) {
  initializeOpenVdb();
  common::AtomicOutput output(path);
  try {
    openvdb::io::File file(output.temporary().string());
    openvdb::GridCPtrVec grids{grid.copyGrid()};
    openvdb::MetaMap metadata(fileMetadata);
    metadata.insertMeta(kWriterKey, openvdb::StringMetadata("rodfab"));
    file.write(grids, metadata);
    file.close();
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot write the grid: " + e.what());
  }
  output.commit();
}

bool isGridFile(const std::string& path) {
  // OpenVDB files start with the magic number 0x56444220 (little-endian " BDV"); the file metadata,
  // with our writer key, follows within the first few hundred bytes.
  return common::fileStartsWith(path, std::string_view(" BDV", 4), kWriterKey, 4096);
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
