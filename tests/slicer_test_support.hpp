// Helpers shared by the slicer library's tests (test_slicer_pipeline.cpp, test_slicer_memory.cpp):
// scratch folders, jobs of boxes, the Connex3 profile, a lowered soft data limit.
#pragma once

#include "calibration/calibration_file.hpp"
#include "common/memory_budget.hpp"
#include "geometry/design_file.hpp"
#include "geometry/rod.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"
#include "slicer/coupon_layout.hpp"
#include "slicer/job_pipeline.hpp"
#include "slicer/slice_design.hpp"
#include "voxel/diagnostics.hpp"
#include "voxel/printer_grid.hpp"
#include "voxel/rasterize.hpp"
#include "tests/temp_dir.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <thread>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

namespace slicer_test {

using namespace rodfab;
namespace fs = std::filesystem;

struct TempDir : rodfab::test::TempDir {
  TempDir() : rodfab::test::TempDir("slicer") {}
};

inline std::string fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline const printer_profiles::Profile& connex3() {
  static const printer_profiles::Profile p = printer_profiles::loadProfile("stratasys-objet500-connex3");
  return p;
}

inline std::uint64_t inspectedVoxels(const printer_profiles::InspectReport& r, printer_profiles::MaterialRole role) {
  std::uint64_t n = 0;
  for (const auto& m : r.materials) n += m.role == role ? m.voxels : 0;
  return n;
}

// Fraction 1 in box `rigid`, 0 in box `rubbery`, for the layers a band asks for.
inline slicer::BandSource twoBoxes(const openvdb::CoordBBox& rigid, const openvdb::CoordBBox& rubbery, const openvdb::Vec3d& originMm) {
  return [=](int k0, int k1, bool withNext) {
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(materials::kFractionGridName);
    grid->setTransform(voxel::printerTransform(connex3().voxelSize(), originMm));
    for (auto [box, value] : {std::pair{rigid, 1.0f}, std::pair{rubbery, 0.0f}}) {
      box.min().z() = std::max(box.min().z(), k0);
      box.max().z() = std::min(box.max().z(), k1 - 1 + (withNext ? 1 : 0));
      if (!box.empty()) grid->tree().denseFill(box, value, true);
    }
    return slicer::BandGrids{grid, nullptr};
  };
}

// A job of part `box` at the origin the box tests use, written to `output`.
inline printer_profiles::JobSpec boxJob(const openvdb::CoordBBox& box, const fs::path& output) {
  printer_profiles::JobSpec spec;
  spec.profile = connex3();
  spec.partBounds = box;
  spec.originMm = openvdb::Vec3d(0.5, 0.5, 0.015);
  spec.options.output = output;
  return spec;
}

// Lowers the soft data limit for the scope: the default memory budget follows it (80 %,
// common/memory_budget.hpp) as under `ulimit -d`. The hard limit stays, so the soft one comes back;
// a lower limit the test runs under is kept (never raised past it).
struct SoftDataLimit {
  rlimit saved{};
  explicit SoftDataLimit(std::uint64_t bytes) {
    REQUIRE(::getrlimit(RLIMIT_DATA, &saved) == 0);
    rlimit lowered = saved;
    lowered.rlim_cur = std::min(rlim_t(bytes), saved.rlim_cur);  // rlim_cur <= rlim_max; RLIM_INFINITY is the largest
    REQUIRE(::setrlimit(RLIMIT_DATA, &lowered) == 0);
  }
  ~SoftDataLimit() { ::setrlimit(RLIMIT_DATA, &saved); }
};

// For a case whose data limit leaves little room besides its own work: the process's data counts
// against the limit, and the cases before it in the same process leave more of it (the heap's arenas:
// 79 MB of data where a fresh process has 40). Runs the test binary again on its own, filtered to
// `filter` (a Catch test spec: a name, `*` allowed, no comma), and returns true in this process, which
// checks that run passed; returns false in that run, which does the work.
inline bool ranInFreshProcess(const std::string& filter) {
  constexpr const char* kMarker = "RODFAB_TEST_FRESH_PROCESS=1";
  if (const char* v = std::getenv("RODFAB_TEST_FRESH_PROCESS"); v && std::string(v) == "1") return false;
  std::vector<char*> environment;
  for (char** e = environ; *e; ++e) environment.push_back(*e);
  environment.push_back(const_cast<char*>(kMarker));
  environment.push_back(nullptr);
  std::string exe = "/proc/self/exe", spec = filter;
  char* argv[] = {exe.data(), spec.data(), nullptr};
  pid_t pid = 0;
  REQUIRE(::posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv, environment.data()) == 0);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  INFO("the case in a process of its own: " << filter);
  CHECK((WIFEXITED(status) && WEXITSTATUS(status) == 0));
  return true;
}

// The message of the common::OutOfMemory sliceDesign refuses `design` with (the test fails if it does not).
inline std::string memoryRefusal(const geometry::RodStructure& design, const calibration::Calibration& cal, materials::Ditherer& ditherer,
                          const slicer::SliceSettings& settings) {
  try {
    slicer::sliceDesign(design, connex3(), cal, ditherer, settings);
  } catch (const common::OutOfMemory& e) {
    return e.what();
  }
  FAIL("expected OutOfMemory");
  return {};
}

}  // namespace slicer_test
