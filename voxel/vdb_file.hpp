// Writing and reading modulus grids as standard .vdb files.
#pragma once

#include <openvdb/openvdb.h>

#include <string>

namespace rodfab::voxel {

// Writes `grid` to `path` under a temporary name in the same folder and renames it into place, so
// `path` is either the old file or the complete new one. Metadata (e.g. the design's name) goes into
// the file header. The bytes depend only on the grid and the metadata: the header's UUID, random in
// OpenVDB's own files, is made from the file's other bytes. Throws std::runtime_error naming the file
// when writing fails (a full disk included: the old file stays, no temporary is left).
void writeGridFile(const std::string& path, const openvdb::GridBase& grid, const openvdb::MetaMap& fileMetadata = {});

// True when `path` is a regular file that writeGridFile wrote (the writer key "rodfab_writer" in its
// file metadata): what `voxelize --output` may replace.
bool isGridFile(const std::string& path);

// Reads the float grid called `gridName` from `path`. Throws std::runtime_error naming the file and the
// grid when it is missing or not a float grid.
openvdb::FloatGrid::Ptr readFloatGrid(const std::string& path, const std::string& gridName);

}  // namespace rodfab::voxel
