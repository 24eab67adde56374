// Progress of a long job on stderr: a live bar on a terminal, plain periodic lines in logs, or nothing.
#pragma once

#include <chrono>
#include <cstddef>
#include <ostream>
#include <string>

namespace rodfab::cli {

class Progress {
public:
  enum class Mode { Quiet, Lines, Bar };
  // Bar when stderr is a terminal, Lines otherwise; Quiet when asked.
  static Mode detect(bool quiet);

  using Clock = std::chrono::steady_clock;
  Progress(std::string unit, std::size_t total, Mode mode, std::ostream& out);

  // `done` units are complete (monotone). Cheap when nothing is due to be printed.
  void update(std::size_t done, Clock::time_point now = Clock::now());
  // Final line (also in Lines mode), with the overall rate.
  void finish(Clock::time_point now = Clock::now());
  // The work ended before it was done: the bar's line is ended where it stands, nothing else printed.
  void stop();

  // "1234/3000 layers (41%), 412 layers/s, 4 s left" — exposed for tests. The rate and the time left
  // appear only after kMinRateSeconds (before that: "1234/3000 layers (41%)").
  static constexpr double kMinRateSeconds = 1.0;
  std::string status(std::size_t done, Clock::time_point now) const;

private:
  std::string unit_;
  std::size_t total_;
  Mode mode_;
  std::ostream& out_;
  Clock::time_point start_, lastPrint_;
  std::size_t lastDone_ = 0;
  int lastDecile_ = -1;
  bool finished_ = false;
  bool barShown_ = false;
};

}  // namespace rodfab::cli
