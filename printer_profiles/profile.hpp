// Printer profiles (`rodfab.printer-profile/1`, JSON): what one printer takes as voxel-printing input.
// Bundled profiles live in this folder and are selected by name; any other file is selected by path.
#pragma once

#include "common/located_issues.hpp"

#include <openvdb/math/Vec3.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

inline constexpr const char* kProfileFormat = "rodfab.printer-profile/1";

// Limits every profile keeps (checked when it is read, each violation named by its JSON path), so that
// a job's file names are portable and its images and previews fit in memory on any profile:
inline constexpr std::size_t kMaxProfileBytes = 1 << 20;  // the profile file
inline constexpr int kMaxProfileDepth = 64;               // JSON nesting (objects and arrays)
inline constexpr std::size_t kMaxFileNameLength = 64;     // material and build-file names
inline constexpr std::size_t kMaxTextLength = 4096;       // name, printer, description, row_order
// The tray in voxels: at most kMaxTrayVoxels image columns, image rows and layers, and at most
// kMaxTrayFacePixels on each face (a layer image: columns x rows; the front and side previews:
// columns x layers, rows x layers). The Connex3 tray is 11,583 x 4,609 x 6,666 voxels.
inline constexpr int kMaxTrayVoxels = 65536;
inline constexpr std::int64_t kMaxTrayFacePixels = std::int64_t{1} << 27;  // 134,217,728
// Other ranges (inclusive): dpi 1..100000; voxel sizes and layer thickness 0.0001..100 mm; tray
// 0 < size <= 10000 mm; density 0 < d <= 100 g/mL; model material slots 1..16; colour components
// 0..255; column alignment 8..4096 (a multiple of 8); padding 0..kMaxTrayVoxels per side with a
// one-voxel part's padded image inside the tray; layer digits 1..9; build file format version 1..1000.

enum class MaterialRole {
  Rigid,    // model material written where the material grid holds `true`
  Rubbery,  // model material written where the material grid holds `false`
  Support,  // deposited by the printer around the model, or by us under overhangs (SupportPolicy::Explicit)
};
const char* toString(MaterialRole role);

enum class ImageFormat { Bmp, Png };
const char* toString(ImageFormat format);
ImageFormat parseImageFormat(const std::string& text);  // "bmp" | "png"; std::invalid_argument otherwise

// What a job for the printer is: per-material 1-bit bitmap stacks with a plain-text build file (the
// Objet Connex3 family), or a GrabCAD Voxel Print file (.gcvf: one RGBA PNG per layer, each colour a
// material, described by ConfigFile.xml; the J750/J850 family; see printer_profiles/README.md).
enum class JobFormat { BitmapStacks, Gcvf };
const char* toString(JobFormat format);  // "bitmap-stacks" | "gcvf"

// A printing mode with its own layer thickness (the J750/J850's high-speed and high-mix modes).
struct PrintMode {
  std::string name;             // a portable name, unique in the profile
  double layerThicknessMm = 0;  // the voxel's z size in this mode
};

// The fixed fields of a GrabCAD Voxel Print ConfigFile.xml (format "gcvf" only).
struct GcvfSettings {
  int version = 2;             // <Version>
  int bitDepth = 4;            // <BitDepth> as GrabCAD's examples write it
  int maxNumberOfColors = 6;   // <MaxNumberOfColors>: distinct colours the printer accepts, background included
  std::string creationMode;    // <CreationMode>, e.g. MODEL_ONLY
  std::string imageFilePrefix; // <ImageFilePrefix>: layer images are PREFIX0.png, PREFIX1.png, ... (no padding)
  std::array<unsigned char, 4> backgroundRgba{};  // <BackGroundMaterialRGBA>: pixels without material
};

enum class SupportPolicy {
  Printer,   // emit no support bitmaps: the printer software adds support around the model
  Explicit,  // emit a support bitmap under every overhang, down to the tray, never overlapping the model
};
const char* toString(SupportPolicy policy);
SupportPolicy parseSupportPolicy(const std::string& text);  // "printer" | "explicit"

struct ProfileMaterial {
  // As the printer software spells it; also the stem of its bitmap files, so a portable file name
  // (see portableNameProblem) unique among the profile's names without regard to case.
  std::string name;
  MaterialRole role = MaterialRole::Rigid;
  double densityGPerMl = 0.0;  // cured density, for mass estimates
  std::array<unsigned char, 3> previewRgb{};
  // The colour that stands for this material in GrabCAD Voxel Print layer images (gcvf profiles: required
  // for the model materials, distinct from each other and from the background).
  std::array<unsigned char, 4> rgba{};
};

struct Profile {
  std::filesystem::path source;  // the file it was read from
  std::string name;              // e.g. "stratasys-objet500-connex3"
  std::string printer;           // human-readable printer name
  std::string description;

  int xDpi = 0, yDpi = 0;                   // image columns (x) and rows (y)
  std::array<double, 3> voxelSizeMm{};      // x, y, z; x and y agree with 25.4 / dpi
  std::array<double, 3> trayMm{};           // usable build volume x, y, z
  int modelMaterialSlots = 0;
  std::vector<ProfileMaterial> materials;   // exactly one rigid, one rubbery and one support material

  ImageFormat imageFormat = ImageFormat::Bmp;  // native format; PNG may be chosen per job
  int columnAlignment = 32;                    // image widths are multiples of this
  std::array<int, 2> paddingVoxels{};          // blank margin around the part in columns (x) and rows (y)
  int layerDigits = 4;                         // layer numbers are zero-padded to this many digits
  std::string rowOrder;                        // why rows run the way they do (documentation for technicians)

  std::string buildFileName;   // the printer's plain-text build file (a portable file name)
  int buildFormatVersion = 1;

  SupportPolicy supportPolicy = SupportPolicy::Printer;  // default; a job may choose the other one

  JobFormat jobFormat = JobFormat::BitmapStacks;  // "output.format"
  GcvfSettings gcvf;                              // format "gcvf" only
  // The printer's modes ("resolution.print_modes"), the first one the default; empty when the printer
  // has one layer thickness. `printMode` names the mode voxelSizeMm[2] is for ("" without modes).
  std::vector<PrintMode> printModes;
  std::string printMode;

  int imageBitDepth() const { return jobFormat == JobFormat::Gcvf ? 32 : 1; }  // RGBA 8 bits each, or 1 bit

  const ProfileMaterial& material(MaterialRole role) const;
  double layerThicknessMm() const { return voxelSizeMm[2]; }
  double voxelVolumeMm3() const { return voxelSizeMm[0] * voxelSizeMm[1] * voxelSizeMm[2]; }
  // voxelSizeMm as the voxel grids take it (voxel::makePrinterGrid, printerTransform): mm, x y z.
  openvdb::math::Vec3d voxelSize() const { return {voxelSizeMm[0], voxelSizeMm[1], voxelSizeMm[2]}; }
  // `<material>_<layer>.<ext>`; layer zero-padded to layerDigits (more digits when it needs them). For
  // format gcvf every material is in the layer's one image, `<gcvf.imageFilePrefix><layer>.png`.
  std::string layerFileName(const ProfileMaterial& material, int layer, ImageFormat format) const;
  // The same with the layer number replaced by x's, as the build file names a whole stack.
  std::string layerFilePattern(const ProfileMaterial& material, ImageFormat format) const;
};

struct ProfileIssue {
  std::string path;     // JSON path such as `materials[1].density_g_per_ml`, or "" for the whole file
  std::string message;  // what was expected
};

// Every violation found in one profile file; what() lists them as `FILE: PATH: MESSAGE`, one per line.
class ProfileError : public common::IssueListError<ProfileIssue> {
public:
  ProfileError(std::string file, std::vector<ProfileIssue> issues);
};

// The bundled profile used when a command or benchmark is not told which printer it is for. Code takes
// the voxel size and the printer transform from a loaded Profile, never from this name.
inline constexpr const char* kDefaultProfileName = "stratasys-objet500-connex3";

// The folder holding the bundled profiles: profiles/ in rodfab's data folder (common/data_dir.hpp);
// throws common::DataDirError when that is not found.
std::filesystem::path bundledProfileDir();
// Names of the bundled profiles, sorted.
std::vector<std::string> bundledProfileNames();

// Why `name` cannot be a file name inside a job on every system a job may be unpacked on, or "" when it
// can: letters, digits, '.', '_' and '-' only (no path separators, drive letters, spaces or controls),
// not starting with '.' or '-', not ending with '.', no Windows device name (CON, PRN, AUX, NUL,
// COM1-9, LPT1-9, with or without an extension), 1..kMaxFileNameLength characters.
std::string portableNameProblem(const std::string& name);

// `profile` in print mode `mode` (its voxel z size that mode's layer thickness). Throws ProfileError
// naming the modes the profile has when it has no mode of that name.
Profile withPrintMode(const Profile& profile, const std::string& mode);

// `nameOrPath` is a bundled profile name (no '/' and no ".json") or the path of a profile file.
// Throws ProfileError (an unknown name lists the bundled ones).
Profile loadProfile(const std::string& nameOrPath);
// Reads at most kMaxProfileBytes from a regular file (a pipe or device is refused, not waited on).
Profile readProfile(const std::filesystem::path& file);
// Refuses JSON nested deeper than kMaxProfileDepth and objects with a key twice before the document
// is built any further, then checks every field against the limits above.
Profile parseProfile(const std::string& text, const std::string& sourceName);

}  // namespace rodfab::printer_profiles
