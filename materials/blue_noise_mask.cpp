#include "materials/blue_noise_mask.hpp"

#include "common/data_dir.hpp"
#include "common/json_input.hpp"

#include "materials/counter_hash.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

namespace rodfab::materials {

namespace {

// Void-and-cluster on a torus with integer energies. Energy(x) = sum over ones y of K(x - y), K a
// truncated Gaussian scaled to integers: additions and removals are exact, so the result does not
// depend on the order of floating-point operations. Ties go to the lowest cell index.
class VoidAndCluster {
public:
  explicit VoidAndCluster(const BlueNoiseParameters& p)
      : nx_(p.size[0]), ny_(p.size[1]), nz_(p.size[2]), cells_(static_cast<std::size_t>(nx_) * ny_ * nz_),
        energy_(cells_, 0), ones_(cells_, 0) {
    buildKernel(p);
    rowCount_ = ny_ * nz_;
    rowBestOne_.resize(rowCount_);
    rowBestZero_.resize(rowCount_);
    planeBestOne_.resize(nz_);
    planeBestZero_.resize(nz_);
  }

  std::vector<std::uint32_t> run(double initialDensity, std::uint64_t seed) {
    // A random start, relaxed until removing the tightest cluster and filling the largest void undo
    // each other: the homogeneous "prototype" pattern.
    std::size_t onesCount = 0;
    for (std::size_t c = 0; c < cells_; ++c) {
      if (unitHash(seed, c) < initialDensity) {
        ones_[c] = 1;
        ++onesCount;
      }
    }
    if (onesCount == 0) {
      ones_[0] = 1;
      onesCount = 1;
    }
    for (std::size_t c = 0; c < cells_; ++c)
      if (ones_[c]) addKernel(c, +1);
    refreshAll();
    for (std::size_t step = 0; step < cells_; ++step) {
      const std::size_t cluster = tightestCluster();
      set(cluster, 0);
      const std::size_t gap = largestVoid();
      set(gap, 1);
      if (gap == cluster) break;
    }
    const std::vector<std::uint8_t> prototypeOnes = ones_;
    const std::vector<std::int64_t> prototypeEnergy = energy_;

    std::vector<std::uint32_t> ranks(cells_, 0);
    // Phase 1: strip the prototype's ones, tightest cluster first, ranks onesCount-1 .. 0.
    for (std::size_t rank = onesCount; rank-- > 0;) {
      const std::size_t cluster = tightestCluster();
      set(cluster, 0);
      ranks[cluster] = static_cast<std::uint32_t>(rank);
    }
    // Phases 2 and 3: from the prototype, fill the largest void until the tile is full. On a torus the
    // zeros' own energy is (kernel sum - energy of the ones), so Ulichney's "tightest cluster of zeros"
    // for the upper half is this same choice.
    ones_ = prototypeOnes;
    energy_ = prototypeEnergy;
    refreshAll();
    for (std::size_t rank = onesCount; rank < cells_; ++rank) {
      const std::size_t gap = largestVoid();
      set(gap, 1);
      ranks[gap] = static_cast<std::uint32_t>(rank);
    }
    return ranks;
  }

private:
  struct Best {
    std::int64_t energy;
    std::size_t cell;  // cells_ when the row/plane has no candidate
  };
  // The kernel as x-runs: weights for dx = -radius .. radius at one (dy, dz).
  struct KernelRow {
    int dy, dz;
    std::vector<std::int64_t> weights;
  };

  void buildKernel(const BlueNoiseParameters& p) {
    std::array<double, 3> sigma{};
    std::array<int, 3> radius{};
    for (int a = 0; a < 3; ++a) {
      sigma[a] = p.sigmaMm / p.voxelSizeMm[a];
      // 3 sigma holds all but 1 % of a Gaussian's weight; never wrap onto itself.
      radius[a] = std::min(static_cast<int>(std::ceil(3.0 * sigma[a])), (p.size[a] - 1) / 2);
    }
    for (int dz = -radius[2]; dz <= radius[2]; ++dz)
      for (int dy = -radius[1]; dy <= radius[1]; ++dy) {
        KernelRow row{dy, dz, {}};
        for (int dx = -radius[0]; dx <= radius[0]; ++dx) {
          const double r2 = dx * dx / (sigma[0] * sigma[0]) + dy * dy / (sigma[1] * sigma[1]) +
                            dz * dz / (sigma[2] * sigma[2]);
          row.weights.push_back(static_cast<std::int64_t>(std::llround(std::ldexp(std::exp(-0.5 * r2), 24))));
        }
        kernel_.push_back(std::move(row));
      }
    radius_ = radius;
  }

  static int wrap(int v, int n) { return v < 0 ? v + n : (v >= n ? v - n : v); }

  void addKernel(std::size_t c, int sign) {
    const int i = static_cast<int>(c % nx_), j = static_cast<int>((c / nx_) % ny_), k = static_cast<int>(c / (nx_ * ny_));
    const int x0 = i - radius_[0];
    const bool wrapsInX = x0 < 0 || i + radius_[0] >= nx_;
    for (const KernelRow& row : kernel_) {
      std::int64_t* line = energy_.data() + (static_cast<std::size_t>(wrap(k + row.dz, nz_)) * ny_ + wrap(j + row.dy, ny_)) * nx_;
      const int n = static_cast<int>(row.weights.size());
      if (wrapsInX) {
        for (int t = 0; t < n; ++t) line[wrap(x0 + t, nx_)] += sign * row.weights[t];
      } else if (sign > 0) {
        for (int t = 0; t < n; ++t) line[x0 + t] += row.weights[t];
      } else {
        for (int t = 0; t < n; ++t) line[x0 + t] -= row.weights[t];
      }
    }
  }

  void refreshRow(int row) {
    Best one{std::numeric_limits<std::int64_t>::min(), cells_};
    Best zero{std::numeric_limits<std::int64_t>::max(), cells_};
    const std::size_t begin = static_cast<std::size_t>(row) * nx_;
    for (std::size_t c = begin; c < begin + nx_; ++c) {
      const std::int64_t e = energy_[c];
      if (ones_[c]) {
        if (e > one.energy) one = {e, c};
      } else if (e < zero.energy) {
        zero = {e, c};
      }
    }
    rowBestOne_[row] = one;
    rowBestZero_[row] = zero;
  }

  void refreshPlane(int k) {
    Best one{std::numeric_limits<std::int64_t>::min(), cells_};
    Best zero{std::numeric_limits<std::int64_t>::max(), cells_};
    for (int row = k * ny_; row < (k + 1) * ny_; ++row) {
      if (rowBestOne_[row].cell != cells_ && rowBestOne_[row].energy > one.energy) one = rowBestOne_[row];
      if (rowBestZero_[row].cell != cells_ && rowBestZero_[row].energy < zero.energy) zero = rowBestZero_[row];
    }
    planeBestOne_[k] = one;
    planeBestZero_[k] = zero;
  }

  void refreshAll() {
    for (int row = 0; row < rowCount_; ++row) refreshRow(row);
    for (int k = 0; k < nz_; ++k) refreshPlane(k);
  }

  // Flips cell c and updates the cached extrema of every row and plane its kernel reached. Where the
  // energies moved in a cache's favour only the touched cells can beat the cached best; where they
  // moved against it the row is rescanned only if its cached best was touched. Same result as a full
  // rescan, a fraction of the work.
  void set(std::size_t c, std::uint8_t value) {
    ones_[c] = value;
    const int sign = value ? +1 : -1;
    addKernel(c, sign);
    const int i = static_cast<int>(c % nx_), j = static_cast<int>((c / nx_) % ny_), k = static_cast<int>(c / (nx_ * ny_));
    const int xReach = std::min(radius_[0], (nx_ - 1) / 2);
    const int yReach = std::min(radius_[1], (ny_ - 1) / 2), zReach = std::min(radius_[2], (nz_ - 1) / 2);
    const int ownRow = static_cast<int>(c / nx_);
    for (int dz = -zReach; dz <= zReach; ++dz) {
      const int kk = wrap(k + dz, nz_);
      for (int dy = -yReach; dy <= yReach; ++dy) {
        const int row = kk * ny_ + wrap(j + dy, ny_);
        if (row == ownRow) {
          refreshRow(row);
          continue;
        }
        const std::size_t begin = static_cast<std::size_t>(row) * nx_;
        Best& one = rowBestOne_[row];
        Best& zero = rowBestZero_[row];
        const auto touched = [&](std::size_t cell) {
          if (cell == cells_) return false;
          const int dx = static_cast<int>(cell - begin) - i;
          return std::min(std::abs(dx), nx_ - std::abs(dx)) <= xReach;
        };
        const bool rescanOne = sign < 0 && touched(one.cell);
        const bool rescanZero = sign > 0 && touched(zero.cell);
        if (rescanOne || rescanZero) {
          refreshRow(row);
          continue;
        }
        if (one.cell != cells_) one.energy = energy_[one.cell];
        if (zero.cell != cells_) zero.energy = energy_[zero.cell];
        for (int dx = -xReach; dx <= xReach; ++dx) {
          const std::size_t cell = begin + wrap(i + dx, nx_);
          const std::int64_t e = energy_[cell];
          if (ones_[cell]) {
            if (sign > 0 && (e > one.energy || (e == one.energy && cell < one.cell) || one.cell == cells_)) one = {e, cell};
          } else if (sign < 0 && (e < zero.energy || (e == zero.energy && cell < zero.cell) || zero.cell == cells_)) {
            zero = {e, cell};
          }
        }
      }
      refreshPlane(kk);
    }
  }

  std::size_t tightestCluster() const {
    Best best{std::numeric_limits<std::int64_t>::min(), cells_};
    for (const Best& b : planeBestOne_)
      if (b.cell != cells_ && b.energy > best.energy) best = b;
    return best.cell;
  }

  std::size_t largestVoid() const {
    Best best{std::numeric_limits<std::int64_t>::max(), cells_};
    for (const Best& b : planeBestZero_)
      if (b.cell != cells_ && b.energy < best.energy) best = b;
    return best.cell;
  }

  int nx_, ny_, nz_;
  std::size_t cells_;
  int rowCount_ = 0;
  std::array<int, 3> radius_{};
  std::vector<KernelRow> kernel_;
  std::vector<std::int64_t> energy_;
  std::vector<std::uint8_t> ones_;
  std::vector<Best> rowBestOne_, rowBestZero_, planeBestOne_, planeBestZero_;
};

// --- file format: see materials/README.md ---

constexpr char kMagic[8] = {'R', 'F', 'B', 'N', 'M', 'A', 'S', 'K'};
constexpr std::uint32_t kVersion = 1;

void putU32(std::string& out, std::uint32_t v) {
  for (int b = 0; b < 4; ++b) out.push_back(static_cast<char>((v >> (8 * b)) & 0xFF));
}
void putU64(std::string& out, std::uint64_t v) {
  for (int b = 0; b < 8; ++b) out.push_back(static_cast<char>((v >> (8 * b)) & 0xFF));
}

std::uint32_t toNanometres(double mm) { return static_cast<std::uint32_t>(std::llround(mm * 1e6)); }

class Reader {
public:
  Reader(const std::filesystem::path& file, const std::string& bytes) : file_(file), bytes_(bytes) {}
  std::uint64_t take(int width, const char* field) {
    if (pos_ + width > bytes_.size()) fail(field, "the file ends early (truncated?)");
    std::uint64_t v = 0;
    for (int b = 0; b < width; ++b) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(bytes_[pos_ + b])) << (8 * b);
    pos_ += width;
    return v;
  }
  [[noreturn]] void fail(const char* field, const std::string& what) const {
    throw std::runtime_error(file_.string() + ": " + field + ": " + what);
  }
  const std::string& bytes() const { return bytes_; }
  std::size_t pos() const { return pos_; }

private:
  std::filesystem::path file_;
  const std::string& bytes_;
  std::size_t pos_ = 0;
};

}  // namespace

BlueNoiseMask::BlueNoiseMask(BlueNoiseParameters parameters, std::vector<std::uint32_t> ranks)
    : parameters_(parameters), ranks_(std::move(ranks)), thresholds_(ranks_.size()) {
  const double n = static_cast<double>(ranks_.size());
  for (std::size_t c = 0; c < ranks_.size(); ++c) thresholds_[c] = static_cast<float>((ranks_[c] + 0.5) / n);
}

BlueNoiseMask BlueNoiseMask::generate(const BlueNoiseParameters& p) {
  for (int a = 0; a < 3; ++a) {
    if (p.size[a] < 2 || p.size[a] > 1024)
      throw std::invalid_argument("blue-noise mask: size " + std::to_string(p.size[a]) + " on axis " +
                                  std::to_string(a) + ", expected 2 .. 1024 voxels");
    if (!(p.voxelSizeMm[a] > 0))
      throw std::invalid_argument("blue-noise mask: voxel size on axis " + std::to_string(a) + " must be > 0 mm (the printer's voxel)");
  }
  if (!(p.sigmaMm > 0)) throw std::invalid_argument("blue-noise mask: sigma must be > 0 mm");
  if (!(p.initialDensity > 0 && p.initialDensity <= 0.5))
    throw std::invalid_argument("blue-noise mask: initial density must be in (0, 0.5]");
  VoidAndCluster generator(p);
  return BlueNoiseMask(p, generator.run(p.initialDensity, p.seed));
}

void BlueNoiseMask::save(const std::filesystem::path& file) const {
  const auto cells = static_cast<std::uint32_t>(ranks_.size());
  const int bits = std::bit_width(cells - 1);
  std::string out(kMagic, sizeof kMagic);
  putU32(out, kVersion);
  for (int a = 0; a < 3; ++a) putU32(out, static_cast<std::uint32_t>(parameters_.size[a]));
  for (int a = 0; a < 3; ++a) putU32(out, toNanometres(parameters_.voxelSizeMm[a]));
  putU32(out, toNanometres(parameters_.sigmaMm));
  putU32(out, static_cast<std::uint32_t>(std::llround(parameters_.initialDensity * 1e6)));
  putU64(out, parameters_.seed);
  putU32(out, static_cast<std::uint32_t>(bits));
  // Ranks as a little-endian bit stream, `bits` per cell, in cell order.
  std::string packed((static_cast<std::size_t>(cells) * bits + 7) / 8, '\0');
  std::size_t bit = 0;
  for (std::uint32_t r : ranks_) {
    for (int b = 0; b < bits; ++b, ++bit)
      if ((r >> b) & 1u) packed[bit / 8] = static_cast<char>(packed[bit / 8] | (1 << (bit % 8)));
  }
  out += packed;
  std::ofstream stream(file, std::ios::binary | std::ios::trunc);
  if (!stream) throw std::runtime_error(file.string() + ": cannot open for writing");
  stream.write(out.data(), static_cast<std::streamsize>(out.size()));
  if (!stream.flush()) throw std::runtime_error(file.string() + ": write failed");
}

BlueNoiseMask BlueNoiseMask::load(const std::filesystem::path& file) {
  // Masks hold at most 2^24 cells (3 bytes of rank each): a larger file is not a mask.
  constexpr std::uint64_t kMaxCells = std::uint64_t{1} << 24;
  constexpr std::size_t kMaxMaskBytes = 3 * kMaxCells + 64;
  std::string bytes;
  try {
    bytes = common::readBoundedFile(file.string(), kMaxMaskBytes);
  } catch (const common::JsonInputError& e) {
    throw std::runtime_error(file.string() + ": cannot read the blue-noise mask: " + e.message);
  }
  Reader in(file, bytes);
  if (in.bytes().size() < sizeof kMagic || std::memcmp(in.bytes().data(), kMagic, sizeof kMagic) != 0)
    in.fail("magic", "expected a rodfab blue-noise mask starting with \"RFBNMASK\"");
  in.take(8, "magic");
  if (const auto version = in.take(4, "version"); version != kVersion)
    in.fail("version", "got " + std::to_string(version) + ", expected " + std::to_string(kVersion));
  BlueNoiseParameters p;
  std::uint64_t cells = 1;
  for (int a = 0; a < 3; ++a) {
    const auto n = in.take(4, "size");
    if (n < 2 || n > 1024) in.fail("size", "got " + std::to_string(n) + ", expected 2 .. 1024 voxels per axis");
    p.size[a] = static_cast<int>(n);
    cells *= n;
  }
  if (cells > kMaxCells)
    in.fail("size", std::to_string(cells) + " cells, expected at most " + std::to_string(kMaxCells));
  for (int a = 0; a < 3; ++a) {
    p.voxelSizeMm[a] = static_cast<double>(in.take(4, "voxel_size_nm")) / 1e6;
    if (!(p.voxelSizeMm[a] > 0)) in.fail("voxel_size_nm", "expected a voxel size > 0 nm");
  }
  p.sigmaMm = static_cast<double>(in.take(4, "sigma_nm")) / 1e6;
  if (!(p.sigmaMm > 0)) in.fail("sigma_nm", "expected a filter width > 0 nm");
  p.initialDensity = static_cast<double>(in.take(4, "initial_density_ppm")) / 1e6;
  p.seed = in.take(8, "seed");
  const auto bits = in.take(4, "bits_per_rank");
  if (bits != static_cast<std::uint64_t>(std::bit_width(cells - 1)))
    in.fail("bits_per_rank", "got " + std::to_string(bits) + ", expected " + std::to_string(std::bit_width(cells - 1)) +
                                 " for " + std::to_string(cells) + " cells");
  const std::size_t payload = (cells * bits + 7) / 8;
  if (in.bytes().size() - in.pos() != payload)
    in.fail("ranks", "expected " + std::to_string(payload) + " bytes of packed ranks, found " +
                         std::to_string(in.bytes().size() - in.pos()));
  const auto* data = reinterpret_cast<const unsigned char*>(in.bytes().data() + in.pos());
  std::vector<std::uint32_t> ranks(cells);
  std::vector<std::uint8_t> seen(cells, 0);
  std::size_t bit = 0;
  for (std::size_t c = 0; c < cells; ++c) {
    std::uint32_t r = 0;
    for (std::uint64_t b = 0; b < bits; ++b, ++bit) r |= static_cast<std::uint32_t>((data[bit / 8] >> (bit % 8)) & 1u) << b;
    if (r >= cells || seen[r])
      in.fail("ranks", "cell " + std::to_string(c) + " has rank " + std::to_string(r) +
                           (r >= cells ? ", out of range" : ", used twice") + ": expected a permutation of 0 .. " +
                           std::to_string(cells - 1));
    seen[r] = 1;
    ranks[c] = r;
  }
  return BlueNoiseMask(p, std::move(ranks));
}

BlueNoiseParameters BlueNoiseParameters::bundledMask() {
  BlueNoiseParameters p;  // size, sigma, density and seed: the member defaults
  p.voxelSizeMm = {0.0423, 0.0846, 0.030};
  return p;
}

std::filesystem::path BlueNoiseMask::bundledPath() {
  const BlueNoiseParameters p = BlueNoiseParameters::bundledMask();
  return common::dataFile(std::filesystem::path("masks") / ("blue-noise-" + std::to_string(p.size[0]) + "x" + std::to_string(p.size[1]) + "x" +
                std::to_string(p.size[2]) + ".rfbn"));
}

std::shared_ptr<const BlueNoiseMask> BlueNoiseMask::bundled() {
  static std::once_flag once;
  static std::shared_ptr<const BlueNoiseMask> mask;
  std::call_once(once, [] { mask = std::make_shared<const BlueNoiseMask>(load(bundledPath())); });
  return mask;
}

}  // namespace rodfab::materials
