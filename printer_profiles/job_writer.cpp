#include "printer_profiles/job_writer.hpp"

#include "common/interrupt.hpp"

#include "printer_profiles/deflate.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/job_manifest.hpp"
#include "printer_profiles/leaf_bits.hpp"
#include "printer_profiles/previews.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cerrno>
#include <charconv>
#include <csignal>
#include <cstdio>  // renameat2, RENAME_EXCHANGE, RENAME_NOREPLACE (glibc 2.28)
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>
#include <system_error>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kPartialTag = ".rodfab-partial-";
// The writer's verification decodes one layer in this many (and the first and last; see verify()).
constexpr int kVerifyDecodeEvery = 32;

void writeFile(const fs::path& path, std::span<const std::uint8_t> data) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  out.close();
  if (!out) throw std::runtime_error(path.string() + ": cannot write (disk full or no permission?)");
}

std::string describeVoxelSize(const openvdb::Vec3d& v) {
  std::ostringstream s;
  s << v.x() << " x " << v.y() << " x " << v.z() << " mm";
  return s.str();
}

bool processAlive(long pid) { return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM); }

constexpr const char* kLockName = ".lock";

// ".NAME.rodfab-partial-PID-N" for the target NAME and this process.
fs::path stagingPath(const fs::path& target, long n) {
  std::string name(".");  // appended piece by piece (GCC 12 warns wrongly about "." + std::string)
  name += target.filename().string();
  name += kPartialTag;
  name += std::to_string(::getpid());
  name += '-';
  name += std::to_string(n);
  return target.parent_path() / name;
}

// ".NAME.rodfab-partial-PID-N" (this version's staging folders), and the names older versions left:
// ".NAME.rodfab-partial-PID-N.zip" and ".NAME.rodfab-partial-PID-old". Returns the PID, or 0 when
// `name` is not exactly one of these.
long stagingPid(const std::string& name) {
  const std::size_t tag = name.rfind(kPartialTag);
  if (name.size() < 2 || name[0] != '.' || tag == std::string::npos || tag < 2) return 0;
  std::string_view rest = std::string_view(name).substr(tag + std::strlen(kPartialTag));
  long pid = 0;
  const auto [end, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), pid);
  if (ec != std::errc() || end == rest.data() || pid <= 0 || pid > std::numeric_limits<pid_t>::max()) return 0;
  rest.remove_prefix(static_cast<std::size_t>(end - rest.data()));
  if (rest == "-old") return pid;
  if (!rest.starts_with('-')) return 0;
  rest.remove_prefix(1);
  if (rest.ends_with(".zip")) rest.remove_suffix(4);
  const bool digits = !rest.empty() && rest.find_first_not_of("0123456789") == std::string_view::npos;
  return digits ? pid : 0;
}

// Whether the staging folder's writer is gone: its lock file is free (flock dies with its holder, so
// a reused pid cannot fool it). Folders without a lock file (older versions, or a writer between
// mkdir and locking) are judged by their pid.
bool writerGone(const fs::path& folder, long pid) {
  const int fd = ::open((folder / kLockName).c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return errno == ENOENT && !processAlive(pid);
  const bool free = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  const bool unsupported = !free && errno != EWOULDBLOCK;
  ::close(fd);  // a later writer cannot take this name: names carry live pids
  return free || (unsupported && !processAlive(pid));
}

// Leftovers of writers that died (killed, crashed) in `folder`, whatever job they were writing: only
// entries named exactly like staging folders (or older versions' temporaries), only when their writer
// is gone; a link is never followed.
void removeDeadStaging(const fs::path& folder) {
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const long pid = stagingPid(name);
    if (!pid) continue;
    std::error_code statusError;
    const fs::file_status status = it->symlink_status(statusError);
    if (statusError) continue;
    std::error_code ignored;
    if (fs::is_directory(status) && writerGone(it->path(), pid)) fs::remove_all(it->path(), ignored);
    else if (fs::is_regular_file(status) && !processAlive(pid)) fs::remove(it->path(), ignored);
  }
}

// The writer's hidden folder beside the target (see JobWriter). Created with its lock file taken;
// removed with everything in it when the object goes, on every path.
class Staging {
public:
  explicit Staging(const fs::path& target) {
    static std::atomic<int> counter{0};
    const fs::path parent = target.parent_path();
    for (int attempt = 0;; ++attempt) {
      root_ = stagingPath(target, counter++);
      if (::mkdir(root_.c_str(), 0777) == 0) break;
      if (errno != EEXIST || attempt == 100) fail(parent, std::strerror(errno), false);
    }
    common::registerCleanup(root_);  // removed on interrupt or a fatal error too (common/interrupt.hpp)
    std::error_code ec;
    fs::create_directories(files() / "previews", ec);
    if (ec) fail(parent, ec.message(), true);
    lock();
  }
  ~Staging() { remove(); }
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;

  const fs::path& root() const { return root_; }
  fs::path files() const { return root_ / "job"; }    // the job's files (a directory job as it will be)
  fs::path zip() const { return root_ / "job.zip"; }  // the zip job
  void remove() {
    std::error_code ec;
    if (!root_.empty()) {
      fs::remove_all(root_, ec);
      common::unregisterCleanup(root_);
    }
    root_.clear();
    if (lockFd_ >= 0) ::close(lockFd_);
    lockFd_ = -1;
  }

private:
  [[noreturn]] void fail(const fs::path& parent, const std::string& why, bool created) {
    std::error_code ignored;
    if (created) fs::remove_all(root_, ignored);
    root_.clear();
    throw std::runtime_error(parent.string() + ": cannot write the job there (" + why + ")");
  }
  // Locked under a name nobody checks, then renamed: whoever finds ".lock" finds it locked while we live.
  void lock() {
    const fs::path initial = root_ / ".lock-init";
    lockFd_ = ::open(initial.c_str(), O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
    if (lockFd_ < 0) fail(root_.parent_path(), std::strerror(errno), true);
    if (::flock(lockFd_, LOCK_EX | LOCK_NB) == 0) {
      if (::rename(initial.c_str(), (root_ / kLockName).c_str()) != 0) fail(root_.parent_path(), std::strerror(errno), true);
      return;
    }
    // A file system without flock: the folder goes by its pid alone, like older versions' folders.
    ::close(lockFd_);
    lockFd_ = -1;
    ::unlink(initial.c_str());
  }

  fs::path root_;
  int lockFd_ = -1;
};

// Linux renameat2: swap two names in one step, or rename without replacing. False when the file
// system does not offer it (the caller falls back); other errors throw, naming both paths (EEXIST for
// RENAME_NOREPLACE: the target appeared, said as such).
bool renameWith(const fs::path& from, const fs::path& to, unsigned flags) {
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), flags) == 0) return true;
  if (errno == EINVAL || errno == ENOSYS || errno == ENOTSUP) return false;
  if (errno == EEXIST && (flags & RENAME_NOREPLACE))
    throw std::runtime_error(to.string() + ": appeared while the job was being written; it was left as it is");
  throw std::system_error(errno, std::generic_category(), "cannot rename " + from.string() + " to " + to.string());
}

void renameOrThrow(const fs::path& from, const fs::path& to) {
  if (::rename(from.c_str(), to.c_str()) != 0)
    throw std::system_error(errno, std::generic_category(), "cannot rename " + from.string() + " to " + to.string());
}

std::string refusal(const fs::path& target, const OutputOccupant& occupant) {
  return target.string() + ": is " + occupant.description +
         "; rodfab replaces only its own jobs (even with --force), so it was left as it is: choose another output";
}

}  // namespace

openvdb::math::Transform::Ptr gridTransform(const Profile& profile, const openvdb::Vec3d& originMm) {
  auto xform = openvdb::math::Transform::createLinearTransform(
      openvdb::math::scale<openvdb::Mat4d>(openvdb::Vec3d(profile.voxelSizeMm[0], profile.voxelSizeMm[1], profile.voxelSizeMm[2])));
  xform->postTranslate(originMm);
  return xform;
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
  const OutputOccupant occupant = examineOutput(t);
  if (occupant.kind == OutputOccupant::Kind::Other) throw std::runtime_error(refusal(t, occupant));
  if (occupant.kind == OutputOccupant::Kind::RodfabJob && !options.force)
    throw std::runtime_error(t.string() + ": " + occupant.description + " already exists there; use --force to replace it");
  return t;
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
  bool finished = false;

  explicit Impl(JobSpec s) : spec(std::move(s)) {
    geometry = planJob(spec.profile, spec.partBounds);
    imageFormat = spec.options.imageFormat.value_or(spec.profile.imageFormat);
    support = spec.options.support.value_or(spec.profile.supportPolicy);
    if (gcvf() && (imageFormat != ImageFormat::Png || support != SupportPolicy::Printer))
      throw std::invalid_argument(spec.profile.name + " jobs are GrabCAD Voxel Print files: PNG layers, support added by GrabCAD "
                                  "(no --image-format bmp, no --support explicit)");
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
    removeDeadStaging(target.parent_path());
    staging = std::make_unique<Staging>(target);  // last: nothing after it may throw
    filesDir = staging->files();
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
    const openvdb::Vec3d want(spec.profile.voxelSizeMm[0], spec.profile.voxelSizeMm[1], spec.profile.voxelSizeMm[2]);
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
    const openvdb::CoordBBox& part = geometry.partBounds;
    const openvdb::CoordBBox allowed(openvdb::Coord(part.min().x(), part.min().y(), band.kBegin),
                                     openvdb::Coord(part.max().x(), part.max().y(), band.kEnd - 1));
    if (!activeWithin(band.material->tree(), allowed)) {
      std::ostringstream msg;
      msg << "addBand: grid '" << band.material->getName() << "' has voxels in " << band.material->evalActiveVoxelBoundingBox()
          << ", outside the band's layers k in [" << band.kBegin << ", " << band.kEnd << ") or the part bounds " << part;
      throw std::invalid_argument(msg.str());
    }
  }

  // Whether every active voxel and tile of `tree` lies in `allowed`. A leaf wholly inside passes by its
  // origin alone; only leaves at the box's faces are scanned voxel by voxel.
  static bool activeWithin(const openvdb::BoolTree& tree, const openvdb::CoordBBox& allowed) {
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
      if (allowed.isInside(openvdb::CoordBBox::createCube(leaf->origin(), openvdb::BoolTree::LeafNodeType::DIM))) continue;
      openvdb::CoordBBox active;
      leaf->evalActiveBoundingBox(active);
      if (!active.empty() && !allowed.isInside(active)) return false;
    }
    bool inside = true;
    forEachActiveTile(tree, [&](const openvdb::CoordBBox& box, bool) { inside = inside && allowed.isInside(box); });
    return inside;
  }

  struct BandLeaf {
    openvdb::Coord origin;
    LeafBytes active, value;
  };

  void encodeBand(const LayerBand& band) {
    const int firstLayer = geometry.layer(band.kBegin);
    const int count = band.kEnd - band.kBegin;
    const int zBase = band.kBegin & ~7;
    // Leaves bucketed by their 8-layer slab; their bytes read once per band.
    std::vector<std::vector<BandLeaf>> slabs(static_cast<std::size_t>((band.kEnd - 1 - zBase) / 8 + 1));
    for (auto leaf = band.material->tree().cbeginLeaf(); leaf; ++leaf)
      slabs[static_cast<std::size_t>((leaf->origin().z() - zBase) / 8)].push_back(
          {leaf->origin(), maskBytes(leaf->getValueMask()), boolValueBytes(*leaf)});
    std::vector<std::pair<openvdb::CoordBBox, bool>> tiles;
    forEachActiveTile(band.material->tree(), [&](const openvdb::CoordBBox& box, bool value) { tiles.emplace_back(box, value); });

    std::vector<LayerBitmaps> bitmaps(static_cast<std::size_t>(count));
    // Zip jobs keep each image's zip form (deflated BMP, or the PNG as it is) in memory until the band
    // is staged in one file: staging thousands of files costs more in the file system than compressing.
    const bool zip = spec.options.archive == ArchiveFormat::Zip;
    std::vector<std::vector<Bytes>> zipForms(zip ? static_cast<std::size_t>(count) : 0);
    const openvdb::FloatGrid* modulus = band.modulus.get();
    tbb::parallel_for(tbb::blocked_range<int>(0, count, 1), [&](const tbb::blocked_range<int>& range) {
      for (int n = range.begin(); n != range.end(); ++n) {
        common::throwIfInterrupted();  // a band of large layers takes seconds
        const int k = band.kBegin + n, layer = firstLayer + n;
        LayerBitmaps& b = bitmaps[static_cast<std::size_t>(n)];
        LayerRecord& record = layers[static_cast<std::size_t>(layer)];
        rasterize(k, slabs[static_cast<std::size_t>((k - zBase) / 8)], tiles, b, record);
        if (support == SupportPolicy::Explicit) addSupport(layer, b);
        record.voxels = {b.rigid.count(), b.rubbery.count(), b.hasSupport ? b.support.count() : 0};
        previews->addLayer(layer, b, modulus);
        writeLayerFiles(layer, b, record, zip ? &zipForms[static_cast<std::size_t>(n)] : nullptr);
      }
    });
    previews->addTopLayers(firstLayer, bitmaps, modulus);
    if (zip) stageBand(firstLayer, zipForms);
  }

  // One staged file per band, the layers' zip forms one after another; named by the band's first
  // layer. Each entry's bytes depend on its image alone, so the band size never shows in the job.
  void stageBand(int firstLayer, const std::vector<std::vector<Bytes>>& zipForms) {
    const fs::path file = staging->root() / ("layers-" + std::to_string(firstLayer) + ".bin");
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    std::uint64_t offset = 0;
    for (std::size_t n = 0; n < zipForms.size(); ++n) {
      LayerRecord& record = layers[static_cast<std::size_t>(firstLayer) + n];
      for (std::size_t f = 0; f < zipForms[n].size(); ++f) {
        const Bytes& data = zipForms[n][f];
        out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
        StagedZipData& z = record.zipped[f];
        z.file = file;
        z.offset = offset;
        offset += data.size();
      }
    }
    out.close();
    if (!out) throw std::runtime_error(file.string() + ": cannot write (disk full or no permission?)");
  }

  ZipStorage layerStorage() const { return imageFormat == ImageFormat::Png ? ZipStorage::Store : ZipStorage::Deflate; }

  void rasterize(int k, const std::vector<BandLeaf>& leaves, const std::vector<std::pair<openvdb::CoordBBox, bool>>& tiles,
                 LayerBitmaps& b, LayerRecord& record) const {
    b.rigid = Bitmap(geometry.width, geometry.height);
    b.rubbery = Bitmap(geometry.width, geometry.height);
    for (const BandLeaf& leaf : leaves) {
      const int z = k - leaf.origin.z();
      const auto byte = static_cast<std::size_t>(geometry.column(leaf.origin.x()) / 8);
      for (int y = 0; y < 8; ++y) {
        const std::uint8_t active = leaf.active.row(y, z);
        if (!active) continue;
        const std::uint8_t value = leaf.value.row(y, z);
        const int j = leaf.origin.y() + y, row = geometry.row(j);
        const auto rigid = static_cast<std::uint8_t>(active & value), rubbery = static_cast<std::uint8_t>(active & ~value);
        b.rigid.row(row)[byte] |= rigid;
        b.rubbery.row(row)[byte] |= rubbery;
        record.moments[0].add(rigid, leaf.origin.x(), j, k);
        record.moments[1].add(rubbery, leaf.origin.x(), j, k);
      }
    }
    for (const auto& [box, value] : tiles) {
      if (k < box.min().z() || k > box.max().z()) continue;
      Bitmap& target = value ? b.rigid : b.rubbery;
      for (int j = box.min().y(); j <= box.max().y(); ++j)
        for (int i = box.min().x(); i <= box.max().x(); i += 8) {
          target.row(geometry.row(j))[geometry.column(i) / 8] = 0xff;  // tiles are 8-aligned in x
          record.moments[value ? 0 : 1].add(0xff, i, j, k);
        }
    }
  }

  // Support fills each column from the tray up to its highest model voxel, wherever the model is not.
  void addSupport(int layer, LayerBitmaps& b) const {
    const ColumnTops& tops = *spec.supportTops;
    b.support = Bitmap(geometry.width, geometry.height);
    b.hasSupport = true;
    for (int r = 0; r < geometry.height; ++r) {
      if (tops.rowMaximum()[static_cast<std::size_t>(r)] <= layer) continue;
      std::uint8_t* out = b.support.row(r);
      const std::uint8_t* rigid = b.rigid.row(r);
      const std::uint8_t* rubbery = b.rubbery.row(r);
      for (std::size_t byte = 0; byte < b.support.stride(); ++byte) {
        std::uint8_t above = 0;
        for (int bit = 0; bit < 8; ++bit)
          if (tops.top(static_cast<int>(byte) * 8 + bit, r) > layer) above = static_cast<std::uint8_t>(above | (0x80u >> bit));
        out[byte] = static_cast<std::uint8_t>(above & ~(rigid[byte] | rubbery[byte]));
      }
    }
  }

  // Encodes the layer's images; writes them to the staging folder, or hands their zip forms to
  // `zipForms` (deflated BMP, PNG as it is) and records their sizes and CRCs in record.zipped.
  void writeLayerFiles(int layer, const LayerBitmaps& b, LayerRecord& record, std::vector<Bytes>* zipForms) const {
    record.files.clear();
    record.zipped.clear();
    const auto keep = [&](const ProfileMaterial& m, Bytes data) {
      FileRecord f{spec.profile.layerFileName(m, layer, imageFormat), data.size(), sha256Hex(data)};
      if (!zipForms) {
        writeFile(filesDir / f.name, data);
      } else {
        StagedZipData z;
        z.size = data.size();
        z.crc32 = zipCrc32(data);
        if (layerStorage() == ZipStorage::Deflate) data = deflateBytes(data, kLayerDeflateLevel, DeflateWrapper::Raw);
        z.length = data.size();
        record.zipped.push_back(z);
        zipForms->push_back(std::move(data));
      }
      record.files.push_back(std::move(f));
    };
    if (gcvf()) {  // one RGBA image holds every material of the layer
      keep(*emitted[0], encodeGcvfLayer(b.rigid, b.rubbery, spec.profile));
      return;
    }
    for (const ProfileMaterial* m : emitted) {
      const Bitmap& bitmap = m->role == MaterialRole::Rigid ? b.rigid : m->role == MaterialRole::Rubbery ? b.rubbery : b.support;
      keep(*m, imageFormat == ImageFormat::Bmp ? encodeBmp(bitmap, spec.profile.xDpi, spec.profile.yDpi)
                                               : encodePng1(bitmap, spec.profile.xDpi, spec.profile.yDpi));
    }
  }

  FileRecord writeStaged(const std::string& name, std::span<const std::uint8_t> data) const {
    writeFile(filesDir / name, data);
    return {name, data.size(), sha256Hex(data)};
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
    return jobManifest({spec, geometry, imageFormat, support, emitted, layers, previews->contactLayers()}, files, previewNames);
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
    entries.push_back({kManifestName, filesDir / kManifestName, ZipStorage::Deflate, std::nullopt});
    for (std::size_t n = 0; n < firstLayerFile; ++n) {
      const bool png = files[n].name.ends_with(".png");
      entries.push_back({files[n].name, filesDir / files[n].name, png ? ZipStorage::Store : ZipStorage::Deflate, std::nullopt});
    }
    for (const LayerRecord& r : layers)
      for (std::size_t f = 0; f < r.files.size(); ++f) entries.push_back({r.files[f].name, {}, layerStorage(), r.zipped[f]});
    writeZip(staging->zip(), entries);
  }

  void verify(const fs::path& built) const {
    InspectOptions options{spec.profile};
    // The layer images' SHA-256 and the zip's CRC-32 were computed over the same bytes (writeLayerFiles):
    // reading each entry back through its CRC proves the zip holds them. Decoding every image again
    // would check the encoders, which the tests do (inspect, the CLI decoder tests); a sample of layers
    // is still decoded, so a broken encoder cannot write a job.
    options.decodeEvery = kVerifyDecodeEvery;
    options.zipCrcForSkippedLayers = true;
    const InspectReport report = inspectJobFiles(*openJobFiles(built), options);
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
    if (spec.options.verify) verify(built);

    checkInterrupt();  // the last moment at which nothing was written
    const Commit commit = commitJob(built);
    try {
      checkInterrupt();
    } catch (...) {
      undo(commit);
      throw;
    }
    finished = true;
    staging->remove();  // temporaries, and the job this one replaced
    return result(files.size() + 1, commit);
  }

  struct Commit {
    bool replaced = false;
    fs::path oldJob;    // where the job it replaced lies now (in the staging folder)
    bool exchanged = false;
    std::uint64_t device = 0, inode = 0;  // of the new job
  };

  // Puts the staged job `built` at the target: a rename that never replaces, or, for a rodfab job
  // there and force, an exchange of the two names in one step. What is at the target is examined
  // again now: it may have changed while the job was written.
  Commit commitJob(const fs::path& built) {
    Commit c;
    struct stat st {};
    if (::lstat(built.c_str(), &st) != 0) throw std::system_error(errno, std::generic_category(), built.string());
    c.device = static_cast<std::uint64_t>(st.st_dev);
    c.inode = static_cast<std::uint64_t>(st.st_ino);
    const OutputOccupant occupant = examineOutput(target);
    if (occupant.kind == OutputOccupant::Kind::Other) throw std::runtime_error(refusal(target, occupant));
    if (occupant.kind == OutputOccupant::Kind::Nothing) {
      if (!renameWith(built, target, RENAME_NOREPLACE)) {
        if (fs::exists(fs::symlink_status(target)))
          throw std::runtime_error(target.string() + ": appeared while the job was being written; it was left as it is");
        renameOrThrow(built, target);
      }
      return c;
    }
    if (!spec.options.force)
      throw std::runtime_error(target.string() + ": a job appeared there while this one was being written; use --force to replace it");
    c.replaced = true;
    c.exchanged = renameWith(built, target, RENAME_EXCHANGE);
    if (c.exchanged) {
      c.oldJob = built;
      // The exchange took whatever was at the target a moment ago: it must be the job examined above.
      const OutputOccupant taken = examineOutput(c.oldJob);
      if (taken.device != occupant.device || taken.inode != occupant.inode) {
        renameWith(c.oldJob, target, RENAME_EXCHANGE);
        throw std::runtime_error(target.string() + ": changed while the job was being written; nothing was replaced");
      }
      return c;
    }
    // No exchange on this file system: the old job is moved aside into the staging folder first.
    c.oldJob = staging->root() / "replaced";
    renameOrThrow(target, c.oldJob);
    try {
      renameOrThrow(built, target);
    } catch (...) {
      renameOrThrow(c.oldJob, target);
      throw;
    }
    return c;
  }

  // Takes a committed job back: the target holds again what it held before (nothing, or the old job).
  void undo(const Commit& c) {
    if (c.exchanged && renameWith(c.oldJob, target, RENAME_EXCHANGE)) return;  // new job back into staging
    renameOrThrow(target, staging->root() / "withdrawn");
    if (c.replaced) renameOrThrow(c.oldJob, target);
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
  impl_->nextK = band.kEnd;
  impl_->encodeBand(band);
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
