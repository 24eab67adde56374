// DMA measurements of printed coupons: the CSV format (see calibration/README.md) and its reader.
#pragma once

#include "common/located_issues.hpp"
#include "common/sha256.hpp"

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace rodfab::calibration {

// One specimen, one CSV row.
struct Measurement {
  double veroFraction = 0.0;  // 0..1
  double modulusMpa = 0.0;    // > 0
  std::optional<double> temperatureC;
  std::string specimen;
  std::string dither;  // the ditherer that made the coupon; empty when not given
  std::string date;
  int line = 0;  // in the source file, for messages
};

struct DataSet {
  std::string source;  // the file name as given (names the data in messages and calibration files)
  std::string sha256;  // of the file's bytes, lowercase hex
  std::vector<Measurement> measurements;
};

struct DataIssue {
  int line = 0;  // 0: the file as a whole
  std::string message;
};

// Every bad row of one file (reading does not stop at the first); what() lists them, one per line,
// as `FILE: line N: MESSAGE`.
class DataError : public common::IssueListError<DataIssue> {
public:
  DataError(std::string file, std::vector<DataIssue> issues);
};

// DMA data sets are a few thousand rows; a larger file is refused before it is read whole.
inline constexpr std::size_t kMaxDataBytes = std::size_t{64} << 20;
// And at most this many measurements, in a data file or a calibration's record of them: every job's
// report plots them (a million took minutes and gigabytes to draw).
inline constexpr std::size_t kMaxMeasurements = 10000;

// Throws DataError (also for an unreadable or oversized file, with line 0).
DataSet readData(const std::filesystem::path& file);
// `sourceName` names the text in messages and in DataSet::source.
DataSet parseData(std::string_view text, const std::string& sourceName);

// SHA-256 of `bytes` as 64 lowercase hex digits (common/sha256.hpp).
using common::sha256Hex;

}  // namespace rodfab::calibration
