// Where rodfab finds its bundled data at run time: printer profiles, the default calibration, the
// blue-noise dither mask and the example designs. The one place that knows; nothing of the machine
// that built rodfab is compiled in, so an installed tree works after it is moved or copied elsewhere.
//
// The data folder has the same layout in the build tree and in an installed tree:
//   profiles/*.json                      printer profiles (printer_profiles/)
//   calibration/default-60C.json         the default calibration and the DMA data it was fitted to
//   masks/blue-noise-64x32x90.rfbn       the blue-noise threshold mask (materials/)
//   examples/                            example designs
// Installed, it is PREFIX/share/rodfab beside PREFIX/bin/rodfab (`cmake --install`, the .deb); in the
// build tree CMake makes BUILD/share/rodfab, whose entries link to the source folders.
//
// Search order (the first that applies wins):
//   1. $RODFAB_DATA_DIR when set and not empty. It must then be a data folder: a wrong value is an
//      error, never silently replaced by another folder.
//   2. EXE/../share/rodfab, then EXE/../../share/rodfab and EXE/../../../share/rodfab, where EXE is the
//      folder of the running executable (/proc/self/exe, symbolic links resolved): bin/ of an
//      installed tree, or a build folder (build/slicer/, build/tests/, build/tests/fuzz/).
// A folder counts as the data folder when it holds a `profiles` folder.
//
// Errors: DataDirError, whose message lists every place looked in and how to fix it.
// Thread safety: reentrant (reads the environment and the file system; nothing is cached).
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::common {

class DataDirError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// The environment variable that overrides the search.
inline constexpr const char* kDataDirVariable = "RODFAB_DATA_DIR";

// The data folder (see the search order above). Throws DataDirError when none is found.
std::filesystem::path dataDir();

// dataDir() / relative, e.g. dataFile("calibration/default-60C.json"). Throws DataDirError when the
// data folder is not found or holds no such file, naming the file and the folder.
std::filesystem::path dataFile(const std::filesystem::path& relative);

// The candidate folders of step 2, in search order, for `executable` (exposed for tests).
std::vector<std::filesystem::path> dataDirCandidates(const std::filesystem::path& executable);

}  // namespace rodfab::common
