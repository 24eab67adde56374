#include "printer_profiles/job_writer.hpp"

#include "common/sha256.hpp"

#include "printer_profiles/band_encoder.hpp"
#include "printer_profiles/deflate.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/job_manifest.hpp"
#include "printer_profiles/job_reader.hpp"  // printableName
#include "printer_profiles/job_staging.hpp"
#include "printer_profiles/leaf_bits.hpp"
#include "printer_profiles/previews.hpp"

#include "common/interrupt.hpp"
#include "common/output_file.hpp"
#include "common/xxh128.hpp"

#include <limits.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string describeVoxelSize(const openvdb::Vec3d& v) {
  std::ostringstream s;
  s << v.x() << " x " << v.y() << " x " << v.z() << " mm";
  return s.str();
}

// A file's deflated zip form, made by igzip at the layers' level as the layers' are: libzip then copies
// it instead of deflating it with zlib on finalize's serial path (the manifest and report.html are
// about a megabyte each). `staged.memory` points into `bytes`, so a form is neither copied nor moved:
// it is made in place (in the writer's map of them).
struct ZipForm {
  Bytes bytes;
  StagedZipData staged;
  explicit ZipForm(std::span<const std::uint8_t> data) : bytes(deflateBytes(data, kLayerDeflateLevel, DeflateWrapper::Raw)) {
    staged.length = bytes.size();
    staged.size = data.size();
    staged.crc32 = zipCrc32(data);
    staged.inMemory = true;
    staged.memory = bytes;
  }
  ZipForm(const ZipForm&) = delete;
  ZipForm& operator=(const ZipForm&) = delete;
};

}  // namespace

bool isDithererLabel(std::string_view label) {
  return label.size() <= 64 &&
         std::all_of(label.begin(), label.end(), [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-'; });
}

fs::path checkJobOutput(const JobOptions& options) {
  fs::path t = options.output;
  if (t.empty()) throw std::invalid_argument("no output path given for the job");
  if (t.filename().empty()) t = t.parent_path();
  t = fs::absolute(t);
  if (t.filename() == "." || t.filename() == ".." || t.filename().empty())
    throw std::runtime_error(t.string() + ": names a folder through '.' or '..'; give the job a name of its own");
  if (stagingPid(t.filename().string()) != 0)  // a later writer would take it for a dead writer's leftovers
    throw std::runtime_error(t.string() + ": is named like rodfab's hidden staging folders (.NAME" + kPartialTag +
                             "PID-N), which later jobs remove; give the job another name");
  if (!fs::is_directory(t.parent_path()))
    throw std::runtime_error(t.parent_path().string() + (fs::exists(t.parent_path())
                                                             ? ": is not a directory; the job needs a folder to go in"
                                                             : ": the output directory does not exist"));
  // Dead writers' leftovers first: a job one of them had moved aside goes back under its name, and the
  // output is examined as the commit will find it.
  removeDeadStaging(t.parent_path());
  common::checkOutputNameLength(t);  // its staging folder's name is longer: refused now, not after the work
  // So are the staging folder's deepest files: job/previews/ and a file name further (at most NAME_MAX).
  const std::size_t deepest = stagingPath(t, 0).string().size() + 12 + std::strlen("/job/previews/") + NAME_MAX;
  if (deepest >= PATH_MAX)
    throw std::runtime_error(t.string() + ": the path is " + std::to_string(t.string().size()) +
                             " bytes long (as an absolute path); the job's files are written in a hidden folder beside it, up to " +
                             std::to_string(deepest - t.string().size()) + " bytes deeper, and the system allows paths of at most " +
                             std::to_string(PATH_MAX - 1) + " bytes: use a shorter path");
  const OutputOccupant occupant = examineOutput(t);
  if (occupant.kind == OutputOccupant::Kind::Other) throw std::runtime_error(refusal(t, occupant));
  if (occupant.kind == OutputOccupant::Kind::RodfabJob && !options.force)
    throw std::runtime_error(t.string() + ": " + occupant.description + " already exists there; use --force to replace it");
  return t;
}

std::uint64_t previewMemoryBytes(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers) {
  if (geometry.width < 1 || geometry.height < 1 || geometry.layers < 1)
    throw std::invalid_argument("previewMemoryBytes: a job geometry of " + std::to_string(geometry.width) + " x " +
                                std::to_string(geometry.height) + " pixels x " + std::to_string(geometry.layers) +
                                " layers has nothing to preview");
  return Previews::heldBytesAtMost(geometry, profile, contactSheetLayers);
}

struct JobWriter::Impl {
  JobSpec spec;
  JobGeometry geometry;
  ImageFormat imageFormat;
  SupportPolicy support;
  std::vector<const ProfileMaterial*> emitted;  // materials with bitmap stacks, in profile order
  fs::path target;
  std::unique_ptr<Staging> staging;
  fs::path filesDir;  // staging->files()
  int nextK = 0;
  std::vector<LayerRecord> layers;
  std::unique_ptr<Previews> previews;
  std::unique_ptr<BandEncoder> encoder;
  std::map<std::string, ZipForm> zipForms;  // by name: the deflated zip forms of writeStaged's files but the PNGs
  bool finished = false;

  explicit Impl(JobSpec s) : spec(std::move(s)) {
    geometry = planJob(spec.profile, spec.partBounds);
    imageFormat = spec.options.imageFormat.value_or(spec.profile.imageFormat);
    support = spec.options.support.value_or(spec.profile.supportPolicy);
    if (gcvf() && (imageFormat != ImageFormat::Png || support != SupportPolicy::Printer))
      throw std::invalid_argument(spec.profile.name + " jobs are GrabCAD Voxel Print files: PNG layers, support added by GrabCAD "
                                  "(no --image-format bmp, no --support explicit)");
    if (spec.metadata.calibration && !common::isSha256Hex(spec.metadata.calibration->sha256))
      throw std::invalid_argument("the job's calibration record's SHA-256 \"" + printableName(spec.metadata.calibration->sha256) +
                                  "\" is not 64 lowercase hexadecimal digits");
    if (!isDithererLabel(spec.metadata.ditherer))
      throw std::invalid_argument("the job's ditherer \"" + printableName(spec.metadata.ditherer) +
                                  "\" is not a label of up to 64 lowercase letters, digits and '-'");
    if (support == SupportPolicy::Explicit) {
      if (!spec.supportTops) throw std::invalid_argument("the explicit support policy needs the part's ColumnTops");
      if (spec.supportTops->width() != geometry.width || spec.supportTops->height() != geometry.height)
        throw std::invalid_argument("ColumnTops was built for another job geometry");
    }
    for (const ProfileMaterial& m : spec.profile.materials)
      if (m.role != MaterialRole::Support || support == SupportPolicy::Explicit) emitted.push_back(&m);
    std::sort(emitted.begin(), emitted.end(), [](const ProfileMaterial* a, const ProfileMaterial* b) { return a->role < b->role; });

    target = checkJobOutput(spec.options);
    nextK = geometry.firstLayerK;
    layers.resize(static_cast<std::size_t>(geometry.layers));
    previews = std::make_unique<Previews>(geometry, spec.profile, spec.options.contactSheetLayers);
    staging = std::make_unique<Staging>(target);  // if anything below throws, its destructor removes the folder
    filesDir = staging->files();
    encoder = std::make_unique<BandEncoder>(BandEncoderSetup{spec.profile, {geometry, imageFormat, support, emitted},
                                                             spec.supportTops.get(), spec.options.archive == ArchiveFormat::Zip,
                                                             filesDir, staging->root(), spec.options.zipFormsInMemory});
  }

  bool gcvf() const { return spec.profile.jobFormat == JobFormat::Gcvf; }

  void checkBand(const LayerBand& band) const {
    if (!band.material) throw std::invalid_argument("addBand: no material grid");
    if (band.kBegin != nextK)
      throw std::invalid_argument("addBand: bands must follow each other in increasing k: expected a band from k = " +
                                  std::to_string(nextK) + ", got k = " + std::to_string(band.kBegin));
    if (band.kEnd <= band.kBegin || band.kEnd > geometry.partBounds.max().z() + 1)
      throw std::invalid_argument("addBand: band [" + std::to_string(band.kBegin) + ", " + std::to_string(band.kEnd) +
                                  ") is empty or runs past the part's top layer k = " +
                                  std::to_string(geometry.partBounds.max().z()));
    // The grid's transform must say the same voxel size as the profile: this catches a 600/300 dpi swap.
    const auto& xform = band.material->transform();
    const openvdb::Vec3d size = xform.voxelSize();
    const openvdb::Vec3d want = spec.profile.voxelSize();
    const auto close = [](double a, double b) { return std::abs(a - b) <= 0.005 * b; };
    if (!xform.isLinear() || !close(size.x(), want.x()) || !close(size.y(), want.y()) || !close(size.z(), want.z())) {
      std::string hint;
      if (close(size.x(), want.y()) && close(size.y(), want.x())) hint = " (x and y are swapped: 600 dpi is x, the image columns)";
      throw std::invalid_argument("addBand: grid '" + band.material->getName() + "' has voxel size " +
                                  describeVoxelSize(size) + "; the " + spec.profile.name + " profile needs " +
                                  describeVoxelSize(want) + hint);
    }
    const openvdb::Vec3d origin = xform.indexToWorld(openvdb::Vec3d(0, 0, 0));
    if ((origin - spec.originMm).length() > 1e-6) {
      std::ostringstream msg;
      msg << "addBand: grid '" << band.material->getName() << "' puts voxel (0,0,0) at " << origin
          << " mm; the job was planned with origin " << spec.originMm << " mm";
      throw std::invalid_argument(msg.str());
    }
  }

  // Where a band's voxels may lie: its layers, within the part's columns and rows.
  openvdb::CoordBBox allowedFor(const LayerBand& band) const {
    const openvdb::CoordBBox& part = geometry.partBounds;
    return {openvdb::Coord(part.min().x(), part.min().y(), band.kBegin), openvdb::Coord(part.max().x(), part.max().y(), band.kEnd - 1)};
  }

  [[noreturn]] void refuseOutside(const LayerBand& band) const {
    std::ostringstream msg;
    msg << "addBand: grid '" << band.material->getName() << "' has voxels in " << band.material->evalActiveVoxelBoundingBox()
        << ", outside the band's layers k in [" << band.kBegin << ", " << band.kEnd << ") or the part bounds " << geometry.partBounds;
    throw std::invalid_argument(msg.str());
  }

  // A file of the job beside its layers: written to the staging folder, or for a zip job, when the zip
  // deflates it, kept only as its zip form.
  FileRecord writeStaged(const std::string& name, std::span<const std::uint8_t> data) {
    if (spec.options.archive == ArchiveFormat::Zip && !name.ends_with(".png")) zipForms.try_emplace(name, data);
    else writeFile(filesDir / name, data);
    return {name, data.size(), common::xxh128Hex(data)};
  }

  std::string buildFileText() const {
    std::ostringstream out;
    const Profile& p = spec.profile;
    out << "[Build]\n"
        << "Format version = " << p.buildFormatVersion << ";\n"
        << "Layer thickness = " << p.layerThicknessMm() << ";\n"
        << "Number of slices = " << geometry.layers << ";\n"
        << "[Resin Type]\n"
        << "Support = " << p.material(MaterialRole::Support).name << ";\n";
    int slot = 1;
    for (const ProfileMaterial* m : emitted)
      if (m->role != MaterialRole::Support) out << "Model" << slot++ << " = " << m->name << ";\n";
    out << "[Materials]\n";
    for (const ProfileMaterial* m : emitted) out << m->name << " = " << p.layerFilePattern(*m, imageFormat) << ";\n";
    return out.str();
  }

  std::vector<GcvfMaterialCount> gcvfCounts() const {
    std::vector<GcvfMaterialCount> counts;
    for (const ProfileMaterial* m : emitted) {
      std::uint64_t n = 0;
      for (const LayerRecord& r : layers) n += r.voxels[static_cast<std::size_t>(m->role)];
      counts.push_back({m, n});
    }
    return counts;
  }

  json manifest(const std::vector<FileRecord>& files, const std::vector<std::string>& previewNames) const {
    return jobManifest({spec, {geometry, imageFormat, support, emitted}, layers, previews->contactLayers()}, files, previewNames);
  }

  void checkInterrupt() const {
    if (spec.options.checkInterrupt) spec.options.checkInterrupt();
  }

  // The build file, previews and manifest beside the layer files; returns every file's record (the
  // layers' last) and the preview names.
  std::vector<FileRecord> writeJobFiles(std::vector<std::string>& previewNames) {
    std::vector<FileRecord> files;
    const std::string build = gcvf() ? gcvfConfigXml(spec.profile, geometry.width, geometry.height, geometry.layers, gcvfCounts())
                                     : buildFileText();
    files.push_back(writeStaged(spec.profile.buildFileName, std::span(reinterpret_cast<const std::uint8_t*>(build.data()), build.size())));
    const std::string title = target.filename().string() + "  -  " + spec.profile.printer + ", " +
                              std::to_string(geometry.width) + " x " + std::to_string(geometry.height) + " px x " +
                              std::to_string(geometry.layers) + " layers";
    const std::vector<std::pair<std::string, Bytes>> rendered = previews->render(title);
    for (const auto& [name, data] : rendered) {
      files.push_back(writeStaged(name, data));
      previewNames.push_back(name);
    }
    if (spec.options.report) files.push_back(writeStaged(kReportName, spec.options.report(manifest({}, previewNames), rendered)));
    for (const LayerRecord& r : layers) files.insert(files.end(), r.files.begin(), r.files.end());
    // Names that are not UTF-8 (a design file's path) are written with U+FFFD rather than failing the job.
    const std::string text = manifest(files, previewNames).dump(1, ' ', false, json::error_handler_t::replace) + "\n";
    writeStaged(kManifestName, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
    return files;
  }

  // Fixed order: manifest, build file, previews, report, then the layers bottom-up, materials in profile order.
  void writeArchive(const std::vector<FileRecord>& files, std::size_t firstLayerFile) const {
    std::vector<ZipEntry> entries;
    entries.push_back({kManifestName, {}, ZipStorage::Deflate, zipForms.at(kManifestName).staged});
    for (std::size_t n = 0; n < firstLayerFile; ++n) {
      // writeStaged decided which files have a zip form (not the PNGs, stored as they are).
      const std::string& name = files[n].name;
      const auto form = zipForms.find(name);
      if (form == zipForms.end()) entries.push_back({name, filesDir / name, ZipStorage::Store, std::nullopt});
      else entries.push_back({name, {}, ZipStorage::Deflate, form->second.staged});
    }
    for (const LayerRecord& r : layers)
      for (std::size_t f = 0; f < r.files.size(); ++f) entries.push_back({r.files[f].name, {}, r.zipped[f].storage, r.zipped[f]});
    encoder->finishStaging();
    writeZip(staging->zip(), entries, encoder->stagedFile());
  }

  void verify(const fs::path& built) const {
    InspectOptions options{spec.profile};
    // A sample of layers is decoded, so a broken encoder cannot write a job; decoding every image again
    // would test the encoders, which the tests do (inspect, the CLI decoder tests). Every other layer
    // image is compared in its stored form with what the band encoder staged: its deflated bytes by the
    // XXH3-128 taken as they were made from the image the manifest describes, its directory record by
    // method, size and CRC-32 (printer_profiles/README.md, "What the writer's own verification checks").
    options.decodeEvery = kVerifyDecodeEvery;
    if (spec.options.archive == ArchiveFormat::Zip) {
      for (const LayerRecord& r : layers)
        for (std::size_t f = 0; f < r.files.size(); ++f) {
          const StagedZipData& z = r.zipped[f];
          options.storedForms.emplace(r.files[f].name, StoredForm{z.xxh128, z.length, z.crc32, z.storage == ZipStorage::Deflate});
        }
    }
    // The staged job is named job.zip or job (never the temporary tag inspectJob refuses), inside the
    // writer's temporary folder.
    const InspectReport report = inspectJob(built, options);
    if (report.ok()) return;
    std::string list;
    for (const std::string& d : report.defects) list += "\n  " + d;
    throw std::runtime_error(target.string() + ": the written job failed verification:" + list);
  }

  JobResult finalize() {
    if (nextK != geometry.partBounds.max().z() + 1)
      throw std::runtime_error("finalize: layers k = " + std::to_string(nextK) + " .. " +
                               std::to_string(geometry.partBounds.max().z()) + " were never added");
    checkInterrupt();
    std::vector<std::string> previewNames;
    const std::vector<FileRecord> files = writeJobFiles(previewNames);
    fs::path built = filesDir;
    if (spec.options.archive == ArchiveFormat::Zip) {
      std::size_t layerFiles = 0;
      for (const LayerRecord& r : layers) layerFiles += r.files.size();
      writeArchive(files, files.size() - layerFiles);
      built = staging->zip();
      checkInterrupt();
    }
    // The zip is written to disk while it is verified, so that commit's fsync finds little left to
    // write (bench/README.md: 0.04 s of a lattice job's 0.23 s finalize). A thread of its own: it
    // mostly waits for the device, which would hold one of TBB's workers.
    std::jthread writeback;
    if (spec.options.archive == ArchiveFormat::Zip) writeback = std::jthread([&built] { common::startWriteback(built); });
    if (spec.options.verify) verify(built);
    if (writeback.joinable()) writeback.join();

    checkInterrupt();  // the last moment at which nothing was written
    const Commit commit = commitJob(built, target, spec.options.force, *staging);
    common::syncFolderEntries(target.parent_path());  // the new name survives a power loss too
    // When a common::CommandOutputs owns the command's outputs, the job this one replaced is kept
    // beside it until the command ends, and put back if the command fails or is interrupted (a signal
    // after this function returned removed the new job and the old one was gone); without an owner it
    // goes with the staging folder below.
    bool kept = false;
    try {
      kept = common::keepCommitted(target, commit.replaced ? commit.oldJob : fs::path());
      checkInterrupt();
    } catch (...) {
      if (kept) common::withdrawCommitted(target);
      else undoCommit(commit, target, *staging);
      throw;
    }
    finished = true;
    staging->remove();  // temporaries, and the job this one replaced unless it is kept
    return result(files.size() + 1, commit);
  }

  JobResult result(std::size_t fileCount, const Commit& commit) const {
    JobResult result;
    result.path = target;
    result.device = commit.device;
    result.inode = commit.inode;
    result.geometry = geometry;
    result.files = fileCount;
    // The job is in place: sizes are only reported, so a file system error here fails nothing.
    std::error_code ec;
    if (spec.options.archive == ArchiveFormat::Zip) {
      result.bytes = fs::file_size(target, ec);
      if (ec) result.bytes = 0;
    } else {
      for (fs::recursive_directory_iterator it(target, ec), end; !ec && it != end; it.increment(ec)) {
        std::error_code sizeError;
        const std::uintmax_t bytes = it->is_regular_file(sizeError) ? it->file_size(sizeError) : 0;
        if (!sizeError) result.bytes += bytes;
      }
    }
    std::array<std::uint64_t, 3> totals{};
    for (const LayerRecord& r : layers)
      for (int role = 0; role < 3; ++role) totals[role] += r.voxels[role];
    for (const ProfileMaterial* m : emitted) {
      const std::uint64_t n = totals[static_cast<std::size_t>(m->role)];
      const double ml = static_cast<double>(n) * spec.profile.voxelVolumeMm3() / 1000.0;
      result.materials.push_back({m->name, m->role, n, ml, ml * m->densityGPerMl});
    }
    return result;
  }
};

JobWriter::JobWriter(JobSpec spec) : impl_(std::make_unique<Impl>(std::move(spec))) {}

JobWriter::~JobWriter() = default;  // the staging folder goes with impl_

const JobGeometry& JobWriter::geometry() const { return impl_->geometry; }
JobMetadata& JobWriter::metadata() { return impl_->spec.metadata; }
ImageFormat JobWriter::imageFormat() const { return impl_->imageFormat; }
SupportPolicy JobWriter::supportPolicy() const { return impl_->support; }

void JobWriter::addBand(LayerBand band) {
  if (impl_->finished) throw std::logic_error("addBand after finalize");
  impl_->checkBand(band);
  // The encoder checks that the voxels lie within the band as it gathers them (one pass over the leaves).
  if (!impl_->encoder->encode(band, impl_->allowedFor(band), impl_->layers, *impl_->previews)) impl_->refuseOutside(band);
  impl_->nextK = band.kEnd;
}

JobResult JobWriter::finalize() {
  if (impl_->finished) throw std::logic_error("finalize called twice");
  return impl_->finalize();
}

bool withdrawJob(const JobResult& result) {
  struct stat st {};
  if (result.path.empty() || ::lstat(result.path.c_str(), &st) != 0 || static_cast<std::uint64_t>(st.st_dev) != result.device ||
      static_cast<std::uint64_t>(st.st_ino) != result.inode)
    return false;
  // Aside under a staging name of this process first: if we die while removing it, a later writer
  // removes the rest; the target never holds half a job.
  static std::atomic<int> counter{0};
  const fs::path aside = stagingPath(result.path, 1000000 + counter++);
  if (::rename(result.path.c_str(), aside.c_str()) != 0) return false;
  std::error_code ec;
  fs::remove_all(aside, ec);
  return true;
}

}  // namespace rodfab::printer_profiles
