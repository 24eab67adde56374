// rodfab coupons: the print job for DMA calibration bars, one uniform bar per Vero fraction, dithered
// with the ditherer the real jobs will use (a mix's stiffness depends on it), each bar labelled in the
// manifest (metadata.coupons) so the measurements can be traced back to fraction and ditherer.
#include "common/stopwatch.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/interrupt.hpp"
#include "slicer/job_options.hpp"
#include "slicer/job_pipeline.hpp"
#include "slicer/job_report.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"
#include "slicer/progress.hpp"

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::cli {

namespace {

using Clock = std::chrono::steady_clock;

// A command-line value that cannot be used (exit kUsage).
struct BadValue : std::runtime_error {
  using std::runtime_error::runtime_error;
};

constexpr std::size_t kMaxCoupons = 1000;

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t"), last = s.find_last_not_of(" \t");
  return first == std::string::npos ? std::string() : s.substr(first, last - first + 1);
}

std::optional<double> parseNumber(const std::string& token) {
  double v = 0.0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::string formatValue(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// "0,0.3,1", or a progression "0,0.1,...,1" (the last two values before "..." give the step, the one
// after it the last value). Each in [0, 1], at least one, no value twice.
std::vector<double> parseFractions(const std::string& text) {
  std::vector<std::string> tokens;
  std::stringstream in(text);
  for (std::string token; std::getline(in, token, ',');) tokens.push_back(trim(token));
  if (!text.empty() && text.back() == ',') tokens.push_back("");
  std::vector<double> out;
  std::vector<std::string> spelled;  // as typed, for the messages
  for (std::size_t t = 0; t < tokens.size(); ++t) {
    const std::string& token = tokens[t];
    if (token == "...") {
      if (out.size() < 2 || t + 2 != tokens.size())
        throw BadValue("--fractions: '...' needs two values before it (the step) and exactly one after it (the last "
                       "value), e.g. 0,0.1,...,1");
      continue;
    }
    const std::optional<double> v = parseNumber(token);
    if (!v) throw BadValue("--fractions: '" + token + "' is not a number");
    if (*v < 0.0 || *v > 1.0) throw BadValue("--fractions: " + token + " is not a Vero fraction in [0, 1]");
    if (t >= 1 && tokens[t - 1] == "...") {
      const double last = out.back(), step = last - out[out.size() - 2];
      const double steps = step == 0.0 ? -1.0 : (*v - last) / step;
      const double n = std::round(steps);
      if (!(n >= 1.0) || std::abs(steps - n) > 1e-6 * std::max(1.0, n))
        throw BadValue("--fractions: steps of " + formatValue(step) + " from " + tokens[t - 2] + " do not reach " + token);
      if (n > static_cast<double>(kMaxCoupons) || out.size() + static_cast<std::size_t>(n) > kMaxCoupons)
        throw BadValue("--fractions: " + text + " makes more than " + std::to_string(kMaxCoupons) + " coupons");
      for (int m = 1; m < static_cast<int>(n); ++m) {
        out.push_back(std::round((last + m * step) * 1e9) / 1e9);
        spelled.push_back(formatValue(out.back()));
      }
    }
    out.push_back(*v);
    spelled.push_back(token);
  }
  if (out.empty())
    throw BadValue("--fractions: expected at least one Vero fraction, e.g. 0,0.1,...,1");
  if (out.size() > kMaxCoupons)
    throw BadValue("--fractions: " + std::to_string(out.size()) + " coupons is more than " + std::to_string(kMaxCoupons));
  // The grid holds floats: two values are the same coupon when they are the same float.
  for (std::size_t a = 0; a < out.size(); ++a)
    for (std::size_t b = 0; b < a; ++b)
      if (static_cast<float>(out[a]) == static_cast<float>(out[b]))
        throw BadValue("--fractions: " + spelled[a] + " is listed twice (as " + spelled[b] + ")");
  return out;
}

// "30x5x1.5" -> {30, 5, 1.5} mm.
std::array<double, 3> parseSize(const std::string& text) {
  std::vector<double> values;
  std::size_t from = 0;
  for (std::size_t x = text.find('x'); from <= text.size(); x = text.find('x', from)) {
    const std::optional<double> v = parseNumber(trim(text.substr(from, x == std::string::npos ? x : x - from)));
    if (!v || !(*v > 0.0)) break;
    values.push_back(*v);
    from = x == std::string::npos ? text.size() + 1 : x + 1;
  }
  if (values.size() != 3 || from != text.size() + 1)
    throw BadValue("--size: expected LENGTHxWIDTHxHEIGHT in mm, three positive numbers such as 30x5x1.5, got '" + text + "'");
  return {values[0], values[1], values[2]};
}

std::string mm(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

// Where the bars lie: rows along x, wrapping into further rows along y, bar 0 top-left as the layer
// images show it (row 0 of the tray = the largest y). Every bar is a box of voxels from layer 0.
struct Layout {
  openvdb::Coord bar;         // voxels per bar along x, y, z
  int gapI = 0, gapJ = 0;     // voxels between bars along x and y
  int perRow = 0, rows = 0;
  std::vector<openvdb::CoordBBox> bars;
  openvdb::CoordBBox bounds;  // all bars

  // The bar holding column (i, j) of the layout, or -1 (a gap or outside).
  int barAt(int i, int j) const {
    if (i < 0 || j < 0) return -1;
    const int pitchI = bar.x() + gapI, pitchJ = bar.y() + gapJ;
    const int column = i / pitchI, rowFromBottom = j / pitchJ;
    if (i % pitchI >= bar.x() || j % pitchJ >= bar.y() || column >= perRow || rowFromBottom >= rows) return -1;
    const std::size_t n = static_cast<std::size_t>((rows - 1 - rowFromBottom) * perRow + column);
    return n < bars.size() ? static_cast<int>(n) : -1;
  }
};

openvdb::CoordBBox rowOf(const openvdb::Coord& bar, int gapI, int count) {
  return {openvdb::Coord(0, 0, 0), openvdb::Coord(count * bar.x() + (count - 1) * gapI - 1, 0, 0)};
}

Layout planLayout(const printer_profiles::Profile& profile, std::size_t count, const openvdb::Coord& bar, int gapI, int gapJ) {
  Layout l;
  l.bar = bar;
  l.gapI = gapI;
  l.gapJ = gapJ;
  // As many bars per row as the tray takes with the images' padding and alignment (planJob decides);
  // a bar too long for the tray stays alone and the whole-layout check below names the overhang.
  int maxPerRow = static_cast<int>(count);
  for (; maxPerRow > 1; --maxPerRow) {
    try {
      printer_profiles::planJob(profile, rowOf(bar, gapI, maxPerRow));
      break;
    } catch (const printer_profiles::TrayFitError&) {
    }
  }
  l.rows = static_cast<int>((count + maxPerRow - 1) / maxPerRow);
  l.perRow = static_cast<int>((count + l.rows - 1) / l.rows);  // balanced rows
  for (std::size_t n = 0; n < count; ++n) {
    const int row = static_cast<int>(n) / l.perRow, column = static_cast<int>(n) % l.perRow;
    const openvdb::Coord min(column * (bar.x() + gapI), (l.rows - 1 - row) * (bar.y() + gapJ), 0);
    l.bars.emplace_back(min, min + bar - openvdb::Coord(1));
  }
  l.bounds = {openvdb::Coord(0), openvdb::Coord(l.perRow * bar.x() + (l.perRow - 1) * gapI - 1,
                                                l.rows * bar.y() + (l.rows - 1) * gapJ - 1, bar.z() - 1)};
  return l;
}

// The job's ditherer, counting the Vero and all voxels of every bar as the bands go by.
class CountingDitherer final : public materials::Ditherer {
public:
  CountingDitherer(materials::Ditherer& inner, const Layout& layout)
      : inner_(inner), layout_(layout), vero_(layout.bars.size(), 0), voxels_(layout.bars.size(), 0) {}

  std::string_view name() const override { return inner_.name(); }
  void reset() override {
    inner_.reset();
    std::fill(vero_.begin(), vero_.end(), 0);
    std::fill(voxels_.begin(), voxels_.end(), 0);
  }
  const std::vector<std::uint64_t>& vero() const { return vero_; }
  const std::vector<std::uint64_t>& voxels() const { return voxels_; }

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override {
    openvdb::BoolGrid::Ptr material = inner_.ditherLayers(fraction, k0, k1);
    for (auto leaf = material->tree().cbeginLeaf(); leaf; ++leaf) {
      const openvdb::CoordBBox box = leaf->getNodeBoundingBox();
      const int bar = layout_.barAt(box.min().x(), box.min().y());
      if (bar >= 0 && bar == layout_.barAt(box.max().x(), box.max().y())) {
        // The whole leaf column lies in one bar: count its bits a word at a time.
        const auto& mask = leaf->getValueMask();
        const auto* values = leaf->buffer().data();
        for (openvdb::Index w = 0; w < mask.WORD_COUNT; ++w) {
          const openvdb::Index64 on = mask.getWord<openvdb::Index64>(w);
          voxels_[static_cast<std::size_t>(bar)] += static_cast<std::uint64_t>(std::popcount(on));
          vero_[static_cast<std::size_t>(bar)] += static_cast<std::uint64_t>(std::popcount(on & values[w]));
        }
        continue;
      }
      for (auto v = leaf->cbeginValueOn(); v; ++v) {
        const int b = layout_.barAt(v.getCoord().x(), v.getCoord().y());
        if (b < 0) throw std::logic_error("coupons: a voxel outside every bar was dithered");
        ++voxels_[static_cast<std::size_t>(b)];
        vero_[static_cast<std::size_t>(b)] += *v ? 1 : 0;
      }
    }
    return material;
  }

private:
  materials::Ditherer& inner_;
  const Layout& layout_;
  std::vector<std::uint64_t> vero_, voxels_;
};

nlohmann::json coord(const openvdb::Coord& c) { return {c.x(), c.y(), c.z()}; }

}  // namespace

int runCoupons(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("output,o", po::value<std::string>()->required(), "the job: NAME.zip, or a folder with --format dir")
      ("fractions", po::value<std::string>()->default_value("0,0.1,...,1"),
       "Vero fractions of the bars, comma-separated; A,B,...,Z continues the step B - A up to Z")
      ("dither", po::value<std::string>()->default_value("white"),
       "white (random, as published) | blue | error-diffusion: the ditherer the jobs will use")
      ("seed", po::value<Seed>()->default_value(Seed{0}), "dithering seed")
      ("size", po::value<std::string>()->default_value("30x5x1.5"), "bar size LENGTHxWIDTHxHEIGHT in mm (length along x)")
      ("gap", po::value<double>()->default_value(5.0), "gap between bars in mm, along x and y")
      ("threads", po::value<int>()->default_value(0), "worker threads (0 = all cores); the job is the same for any count")
      ("format", po::value<std::string>()->default_value("zip"), "zip | dir")
      ("image-format", po::value<std::string>(), "bmp | png (default: the profile's)")
      ("band-layers", po::value<int>()->default_value(64), "layers per streamed band")
      ("force", "replace an existing job at --output")
      ("quiet,q", "no progress bar or progress lines on stderr (the summary, warnings and errors are still printed)")
      ("json", "print the job summary as JSON on stdout");
  addProfileOptions(options);
  po::positional_options_description positional;
  po::variables_map vm;
  const char* synopsis =
      "--output JOB.zip [--fractions 0,0.1,...,1] [--dither white|blue|error-diffusion] [--seed N] [--size 30x5x1.5] "
      "[--gap 5] [--profile NAME|FILE] [--print-mode MODE] [--threads N] [--format zip|dir] [--image-format bmp|png] [--force] [--quiet] [--json]";
  if (auto code = parseOptions("coupons", synopsis, options, positional, args, vm)) return *code;

  const auto usageError = [](const std::string& message) { return cli::usageError("coupons", message); };
  const std::optional<int> threadsOption = threadCount("coupons", vm);
  if (!threadsOption) return kUsage;
  const int threads = *threadsOption;
  const std::optional<int> bandOption = intOption("coupons", vm, "band-layers", 1, kMaxBandLayers);
  if (!bandOption) return kUsage;
  const int bandLayers = *bandOption;
  printer_profiles::JobOptions jobOptions;
  if (auto error = parseJobOptions(vm, jobOptions)) return usageError(*error);
  // The writer asks again right before and right after renaming the job into place (README: an
  // interrupted command writes no job).
  jobOptions.checkInterrupt = [] { throwIfInterrupted(); };
  const std::string format = vm["format"].as<std::string>();
  std::vector<double> fractions;
  std::array<double, 3> sizeMm{};
  try {
    fractions = parseFractions(vm["fractions"].as<std::string>());
    sizeMm = parseSize(vm["size"].as<std::string>());
  } catch (const BadValue& e) {
    return usageError(e.what());
  }
  const double gapMm = vm["gap"].as<double>();
  if (!(gapMm > 0.0 && gapMm <= 1000.0)) return usageError("--gap: expected a gap in mm, > 0 and at most 1000, got " + formatValue(gapMm));
  materials::DitherOptions ditherOptions;
  ditherOptions.seed = vm["seed"].as<Seed>().value;
  std::unique_ptr<materials::Ditherer> ditherer;
  try {
    ditherer = materials::makeDitherer(materials::canonicalDitherName(vm["dither"].as<std::string>()), ditherOptions);
  } catch (const std::invalid_argument& e) {
    return usageError(std::string("--dither: ") + e.what());
  }
  const std::string ditherName(ditherer->name());

  const auto tStart = Clock::now();
  std::unique_ptr<tbb::global_control> threadLimit;
  if (threads > 0)
    threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  const std::optional<printer_profiles::Profile> profileOption = profileFromOptions(vm, "no job was written");
  if (!profileOption) return kFailed;
  const printer_profiles::Profile& profile = *profileOption;
  const std::array<double, 3>& voxel = profile.voxelSizeMm;

  // Bar and gap sizes in whole voxels, the nearest to what was asked.
  const char* axis[3] = {"x", "y", "z"};
  std::array<double, 3> barVoxelsD{};
  for (int a = 0; a < 3; ++a) {
    barVoxelsD[a] = std::round(sizeMm[a] / voxel[a]);
    if (barVoxelsD[a] < 1.0)
      return usageError("--size: " + formatValue(sizeMm[a]) + " mm along " + axis[a] + " is less than one voxel (" +
                        formatValue(voxel[a]) + " mm)");
  }
  // Checked before the sizes become voxel indices, so a bar many times the tray cannot overflow them.
  std::string tooLarge;
  for (int a = 0; a < 3; ++a)
    if (barVoxelsD[a] * voxel[a] > profile.trayMm[a] + 1e-9)
      tooLarge += std::string(tooLarge.empty() ? "" : ", ") + "by " + mm(barVoxelsD[a] * voxel[a] - profile.trayMm[a]) +
                  " mm along " + axis[a];
  if (!tooLarge.empty()) {
    std::cerr << "rodfab coupons: a bar of " << mm(barVoxelsD[0] * voxel[0]) << " x " << mm(barVoxelsD[1] * voxel[1]) << " x "
              << mm(barVoxelsD[2] * voxel[2]) << " mm does not fit the " << profile.printer << " tray ("
              << mm(profile.trayMm[0]) << " x " << mm(profile.trayMm[1]) << " x " << mm(profile.trayMm[2])
              << " mm): too large " << tooLarge << "\nno job was written\n";
    return kFailed;
  }
  const openvdb::Coord barVoxels(static_cast<int>(barVoxelsD[0]), static_cast<int>(barVoxelsD[1]), static_cast<int>(barVoxelsD[2]));
  const int gapI = static_cast<int>(std::round(gapMm / voxel[0])), gapJ = static_cast<int>(std::round(gapMm / voxel[1]));
  if (gapI < 1 || gapJ < 1)
    return usageError("--gap: " + formatValue(gapMm) + " mm is less than one voxel along " + (gapI < 1 ? "x" : "y") + " (" +
                      formatValue(voxel[gapI < 1 ? 0 : 1]) + " mm): the bars would touch");

  const Layout layout = planLayout(profile, fractions.size(), barVoxels, gapI, gapJ);
  const std::array<double, 3> barMm = {barVoxels.x() * voxel[0], barVoxels.y() * voxel[1], barVoxels.z() * voxel[2]};
  const std::string barText = mm(barMm[0]) + " x " + mm(barMm[1]) + " x " + mm(barMm[2]) + " mm";
  try {
    printer_profiles::planJob(profile, layout.bounds);
  } catch (const printer_profiles::TrayFitError& e) {
    std::cerr << "rodfab coupons: " << fractions.size() << " bar(s) of " << barText << " with " << mm(gapMm)
              << " mm gaps, " << layout.rows << " row(s) of up to " << layout.perRow << ": " << e.what()
              << "\nno job was written\n";
    return kFailed;
  }

  // Voxel (i, j, k) spans [i, i + 1) x voxel size in mm: the layout starts at the frame's origin.
  const openvdb::Vec3d originMm(voxel[0] / 2, voxel[1] / 2, voxel[2] / 2);
  const auto cornerMm = [&](const openvdb::Coord& c) {
    return nlohmann::json{c.x() * voxel[0], c.y() * voxel[1], c.z() * voxel[2]};
  };

  printer_profiles::JobSpec spec;
  spec.profile = profile;
  spec.partBounds = layout.bounds;
  spec.originMm = originMm;
  spec.metadata.ditherer = ditherName;
  spec.metadata.seed = ditherOptions.seed;
  spec.options = jobOptions;
  // report.html (slicer/job_report.hpp): coupons record no calibration or clamping; the rest applies.
  spec.options.report = [verified = jobOptions.verify](const nlohmann::json& manifest, const auto& previews) {
    slicer::ReportInputs inputs;
    inputs.verified = verified;
    const std::string page = slicer::renderJobReport(manifest, previews, inputs);
    return printer_profiles::Bytes(page.begin(), page.end());
  };

  commandLineAccepted();
  // The output is refused now (a user's folder, a job without --force) rather than after the work.
  printer_profiles::checkJobOutput(jobOptions);
  InterruptGuard interrupts;
  const Progress::Mode mode = Progress::detect(vm.count("quiet") > 0);
  Progress progress("layers", static_cast<std::size_t>(barVoxels.z()), mode, std::cerr);
  CountingDitherer counting(*ditherer, layout);

  // Layers [k0, k1) of every bar (and layer k1 when asked), each voxel at its bar's fraction.
  const slicer::BandSource source = [&](int k0, int k1, bool withNextLayer) {
    throwIfInterrupted();
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(materials::kFractionGridName);
    grid->setTransform(printer_profiles::gridTransform(profile, originMm));
    const int top = k1 - 1 + (withNextLayer ? 1 : 0);
    for (std::size_t n = 0; n < layout.bars.size(); ++n) {
      openvdb::CoordBBox box = layout.bars[n];
      box.min().z() = std::max(box.min().z(), k0);
      box.max().z() = std::min(box.max().z(), top);
      if (!box.empty()) grid->tree().denseFill(box, static_cast<float>(fractions[n]), true);  // leaf voxels, no tiles
    }
    return slicer::BandGrids{grid, nullptr};
  };

  nlohmann::json bars = nlohmann::json::array();
  slicer::PipelineOptions pipeline;
  pipeline.bandLayers = bandLayers;
  pipeline.onBand = [&](int done, int) {
    progress.update(static_cast<std::size_t>(done));
    throwIfInterrupted();
  };
  pipeline.beforeFinalize = [&](printer_profiles::JobMetadata& metadata) {
    for (std::size_t n = 0; n < layout.bars.size(); ++n) {
      const openvdb::CoordBBox& b = layout.bars[n];
      const std::uint64_t all = counting.voxels()[n], vero = counting.vero()[n];
      char specimen[32];
      std::snprintf(specimen, sizeof specimen, "coupon-%02zu", n);
      bars.push_back({{"index", n},
                      {"specimen", specimen},
                      {"vero_fraction", fractions[n]},
                      {"ditherer", ditherName},
                      {"seed", ditherOptions.seed},
                      {"row", static_cast<int>(n) / layout.perRow},
                      {"column", static_cast<int>(n) % layout.perRow},
                      {"position_mm", cornerMm(b.min())},
                      {"bounds_mm", {{"min", cornerMm(b.min())}, {"max", cornerMm(b.max() + openvdb::Coord(1))}}},
                      {"bounds_voxels", {{"min", coord(b.min())}, {"max", coord(b.max())}}},
                      {"size_mm", barMm},
                      {"voxels", all},
                      {"vero_voxels", vero},
                      {"vero_share", all ? static_cast<double>(vero) / static_cast<double>(all) : 0.0}});
    }
    metadata.extra["coupons"] = {
        {"purpose", "DMA calibration bars: measure each, then fit with rodfab calibrate, recording its vero_fraction "
                    "and ditherer (the data's dither column)"},
        {"ditherer", ditherName},
        {"seed", ditherOptions.seed},
        {"requested_size_mm", sizeMm},
        {"size_voxels", coord(barVoxels)},
        {"size_mm", barMm},
        {"gap_mm", {gapI * voxel[0], gapJ * voxel[1]}},
        {"rows", layout.rows},
        {"per_row", layout.perRow},
        {"position_note", "min corner of each bar in the manifest frame's mm; voxel (i, j, k) spans [i, i + 1) x the voxel size"},
        {"bars", bars}};
  };

  slicer::StageSeconds seconds;
  printer_profiles::JobResult job;
  try {
    job = slicer::streamJob(spec, source, counting, pipeline, seconds);
    common::registerCleanup(job.path);  // until the command returns, a signal still removes the job
  } catch (const Interrupted& e) {
    progress.finish();
    std::cerr << "rodfab coupons: " << e.what() << '\n';
    return 128 + e.signal;
  }
  progress.finish();
  const double total = common::secondsSince(tStart);
  // A signal that came after the job was renamed into place still means no job (README): take it back.
  const auto finish = [&job] {
    const int signal = InterruptGuard::pending();
    if (!signal) return static_cast<int>(kOk);
    printer_profiles::withdrawJob(job);
    std::cerr << "rodfab coupons: " << Interrupted(signal).what() << '\n';
    return 128 + signal;
  };

  for (std::size_t n = 0; n < layout.bars.size(); ++n)
    if (counting.voxels()[n] != static_cast<std::uint64_t>(layout.bars[n].volume()))
      throw std::logic_error("coupons: bar " + std::to_string(n) + " was dithered with " + std::to_string(counting.voxels()[n]) +
                             " voxels, expected " + std::to_string(layout.bars[n].volume()));

  const printer_profiles::JobGeometry& g = job.geometry;
  const double heightMm = g.layers * profile.layerThicknessMm();
  if (vm.count("json")) {
    nlohmann::json materialsJson = nlohmann::json::array();
    for (const auto& m : job.materials)
      materialsJson.push_back({{"name", m.name}, {"role", printer_profiles::toString(m.role)}, {"voxels", m.voxels},
                               {"volume_ml", m.volumeMl}, {"mass_g", m.massG}});
    const nlohmann::json j{{"job", job.path.string()},
                           {"profile", profile.name},
                           {"layers", g.layers},
                           {"image_size", {g.width, g.height}},
                           {"print_height_mm", heightMm},
                           {"ditherer", ditherName},
                           {"seed", ditherOptions.seed},
                           {"size_mm", barMm},
                           {"size_voxels", coord(barVoxels)},
                           {"rows", layout.rows},
                           {"per_row", layout.perRow},
                           {"bars", bars},
                           {"materials", materialsJson},
                           {"files", job.files},
                           {"bytes", job.bytes},
                           {"seconds", {{"bars", seconds.source}, {"dither", seconds.dither}, {"emit", seconds.emit}, {"total", total}}}};
    std::cout << j.dump(2) << '\n';
    return finish();
  }
  std::printf("job:         %s (%s, %zu files, %.1f MB)\n", job.path.c_str(), format.c_str(), job.files,
              static_cast<double>(job.bytes) / 1e6);
  std::printf("printer:     %s (%s)\n", profile.printer.c_str(), profile.name.c_str());
  std::printf("coupons:     %zu bars of %s (%d x %d x %d voxels; asked %s x %s x %s mm), %s mm gaps; %d row%s of %d\n",
              fractions.size(), barText.c_str(), barVoxels.x(), barVoxels.y(), barVoxels.z(), formatValue(sizeMm[0]).c_str(),
              formatValue(sizeMm[1]).c_str(), formatValue(sizeMm[2]).c_str(), formatValue(gapMm).c_str(), layout.rows,
              layout.rows == 1 ? "" : "s", layout.perRow);
  std::printf("layers:      %d x %.3f mm = %.2f mm print height; images %d x %d px\n", g.layers, profile.layerThicknessMm(),
              heightMm, g.width, g.height);
  std::printf("dithering:   %s, seed %llu\n", ditherName.c_str(), static_cast<unsigned long long>(ditherOptions.seed));
  std::printf("  bar  specimen   fraction  Vero share   x, y of the min corner (mm)\n");
  for (const nlohmann::json& b : bars)
    std::printf("  %3d  %-9s  %8.3f  %10.4f   %.3f, %.3f\n", b["index"].get<int>(), b["specimen"].get<std::string>().c_str(),
                b["vero_fraction"].get<double>(), b["vero_share"].get<double>(), b["position_mm"][0].get<double>(),
                b["position_mm"][1].get<double>());
  for (const auto& m : job.materials)
    std::printf("  %-14s %-8s %15s voxels  %9.3f mL  %9.3f g\n", m.name.c_str(), printer_profiles::toString(m.role),
                formatCount(m.voxels).c_str(), m.volumeMl, m.massG);
  std::printf("time:        %.2f s bars, %.2f s dither, %.2f s emit; %.2f s total\n", seconds.source, seconds.dither,
              seconds.emit, total);
  std::printf("next:        measure the bars, put each one's fraction and '%s' (dither column) in the DMA data, rodfab calibrate\n",
              ditherName.c_str());
  return finish();
}

}  // namespace rodfab::cli
