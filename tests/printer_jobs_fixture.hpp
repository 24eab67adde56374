// Shared by the job tests (tests/test_printer_jobs.cpp, test_printer_jobs_commit.cpp): synthetic
// material grids, jobs written from them band by band, and an independent decoder that maps a job's
// images back to voxels through the manifest's frame.
#pragma once

#include "printer_profiles/printer_profiles.hpp"
#include "tests/printer_profiles_fixture.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <map>
#include <random>
#include <set>
#include <string>
#include <tuple>

namespace rodfab::test {

using namespace printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;

inline const openvdb::Vec3d kOrigin(-3.0, 5.0, 0.25);

inline openvdb::BoolGrid::Ptr newGrid() {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("material");
  grid->setTransform(rodfab::test::profileTransform(connex3(), kOrigin));
  return grid;
}

// A box with a random Vero/Tango pattern, plus a slab overhanging one side at the top.
inline openvdb::BoolGrid::Ptr overhangPart(unsigned seed) {
  auto grid = newGrid();
  auto acc = grid->getAccessor();
  std::mt19937 rng(seed);
  std::bernoulli_distribution vero(0.4);
  for (int k = 3; k < 23; ++k)
    for (int j = -7; j < 9; ++j)
      for (int i = 5; i < 21; ++i) acc.setValueOn({i, j, k}, vero(rng));
  for (int k = 23; k < 27; ++k)  // the overhang: wider than the box along x
    for (int j = -7; j < 9; ++j)
      for (int i = 5; i < 47; ++i) acc.setValueOn({i, j, k}, vero(rng));
  return grid;
}

// The band of layers [kBegin, kEnd) of `grid`, as the slicer would hand it over.
inline openvdb::BoolGrid::Ptr band(const openvdb::BoolGrid& grid, int kBegin, int kEnd) {
  auto out = newGrid();
  auto acc = out->getAccessor();
  for (auto it = grid.cbeginValueOn(); it; ++it)
    if (it.getCoord().z() >= kBegin && it.getCoord().z() < kEnd) acc.setValueOn(it.getCoord(), *it);
  return out;
}

inline JobSpec specFor(const openvdb::BoolGrid& grid, const fs::path& output) {
  JobSpec spec;
  spec.profile = connex3();
  spec.partBounds = grid.evalActiveVoxelBoundingBox();
  spec.originMm = kOrigin;
  spec.metadata.design = "synthetic";
  spec.metadata.ditherer = "white-noise";
  spec.metadata.seed = 7;
  spec.options.output = output;
  spec.options.contactSheetLayers = 6;
  return spec;
}

inline JobResult writeJob(const openvdb::BoolGrid& grid, JobSpec spec, int bandLayers) {
  JobWriter writer(std::move(spec));
  const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  for (int k = box.min().z(); k <= box.max().z(); k += bandLayers)
    writer.addBand({band(grid, k, std::min(k + bandLayers, box.max().z() + 1)), nullptr, k, std::min(k + bandLayers, box.max().z() + 1)});
  return writer.finalize();
}

using Voxel = std::tuple<int, int, int, int>;  // i, j, k, material (1 rigid, 0 rubbery, 2 support)

// Decodes every layer image of a job and maps pixels back to voxels through the manifest's frame.
inline std::set<Voxel> decodeJob(const fs::path& job, json* manifestOut = nullptr) {
  const auto files = openJobFiles(job);
  const Bytes text = files->read("manifest.json");
  const json manifest = json::parse(text.begin(), text.end());
  if (manifestOut) *manifestOut = manifest;
  const int i0 = manifest["frame"]["first_column_i"], j0 = manifest["frame"]["top_row_j"], k0 = manifest["frame"]["first_layer_k"];
  std::map<std::string, int> code;
  for (const json& m : manifest["materials"])
    code[m["name"]] = m["role"] == "rigid" ? 1 : m["role"] == "rubbery" ? 0 : 2;
  std::set<Voxel> voxels;
  for (const json& layer : manifest["layers"])
    for (const auto& [material, file] : layer["files"].items()) {
      const Bytes data = files->read(file.get<std::string>());
      const std::string name = file.get<std::string>();
      const DecodedBitmap d = name.ends_with(".png") ? decodePng1(data) : decodeBmp(data);
      REQUIRE(d.bitDepth == 1);
      for (int r = 0; r < d.bitmap.height(); ++r)
        for (int c = 0; c < d.bitmap.width(); ++c)
          if (d.bitmap.get(c, r)) voxels.emplace(i0 + c, j0 - r, k0 + layer["layer"].get<int>(), code[material]);
    }
  return voxels;
}

// Everything below `root` without following links: relative path -> kind and contents (bytes or link
// target), so a folder can be compared byte for byte before and after.
inline std::map<std::string, std::string> snapshot(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    const std::string name = fs::relative(it->path(), root).generic_string();
    const fs::file_status status = it->symlink_status();
    if (fs::is_symlink(status)) out[name] = "link:" + fs::read_symlink(it->path()).string();
    else if (fs::is_directory(status)) out[name] = "dir";
    else if (!fs::is_regular_file(status)) out[name] = "special";
    else {
      const Bytes data = readAll(it->path());
      out[name] = "file:" + std::string(data.begin(), data.end());
    }
  }
  return out;
}

inline std::set<Voxel> gridVoxels(const openvdb::BoolGrid& grid) {
  std::set<Voxel> voxels;
  for (auto it = grid.cbeginValueOn(); it; ++it) voxels.emplace(it.getCoord().x(), it.getCoord().y(), it.getCoord().z(), *it ? 1 : 0);
  return voxels;
}

}  // namespace rodfab::test
