// calibration/: throughput of the modulus-to-fraction query (what materials/ calls per voxel) for each
// model, and the cost of a fit with replicates. Items are voxels (queries).
#include "calibration/calibration.hpp"

#include <benchmark/benchmark.h>

#include <sys/resource.h>

#include <cmath>
#include <sstream>
#include <vector>

using namespace rodfab::calibration;

namespace {

// The published 60 C figures plus replicates on a log-power law, so pchip has several intervals.
std::string benchCsv() {
  std::ostringstream csv;
  csv.precision(17);
  csv << "vero_fraction,modulus_mpa\n";
  for (double f : {0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0})
    for (double factor : {0.95, 1.0, 1.05}) csv << f << ',' << factor * std::exp(std::log(0.5) + std::log(380.0) * std::pow(f, 0.63)) << '\n';
  return csv.str();
}

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

void fractionQuery(benchmark::State& state) {
  const Calibration c = fitCalibration(parseData(benchCsv(), "bench.csv"), {static_cast<Model>(state.range(0)), kDefaultFloorMpa});
  // Log-spaced requests from 1 to 250 MPa: about a quarter below the floor, some above the maximum.
  std::vector<double> moduli(1 << 16);
  for (std::size_t i = 0; i < moduli.size(); ++i) moduli[i] = std::pow(250.0, static_cast<double>(i) / (moduli.size() - 1));
  ClampCounts clamps;
  double sum = 0;
  for (auto _ : state) {
    for (double e : moduli) {
      const FractionResult r = c.fraction(e);
      sum += r.fraction;
      clamps.count(r.clamp);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetLabel(std::string(modelName(c.model())));
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * moduli.size()));
  state.counters["clamped_share"] = static_cast<double>(clamps.total()) / static_cast<double>(state.iterations() * moduli.size());
  state.counters["peak_rss_MB"] = peakRssMb();
}
BENCHMARK(fractionQuery)->Arg(static_cast<int>(Model::Pchip))->Arg(static_cast<int>(Model::Lichtenecker))->Arg(static_cast<int>(Model::LogPower));

void fit(benchmark::State& state) {
  const DataSet data = parseData(benchCsv(), "bench.csv");
  for (auto _ : state) benchmark::DoNotOptimize(fitCalibration(data, {static_cast<Model>(state.range(0)), kDefaultFloorMpa}));
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
  state.counters["peak_rss_MB"] = peakRssMb();
}
BENCHMARK(fit)->Arg(static_cast<int>(Model::Pchip))->Arg(static_cast<int>(Model::Lichtenecker))->Arg(static_cast<int>(Model::LogPower));

}  // namespace
