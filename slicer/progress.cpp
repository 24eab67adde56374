#include "slicer/progress.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace rodfab::cli {

Progress::Mode Progress::detect(bool quiet) {
  if (quiet) return Mode::Quiet;
  return isatty(STDERR_FILENO) ? Mode::Bar : Mode::Lines;
}

Progress::Progress(std::string unit, std::size_t total, Mode mode, std::ostream& out)
    : unit_(std::move(unit)), total_(total), mode_(mode), out_(out), start_(Clock::now()), lastPrint_(start_) {}

std::string Progress::status(std::size_t done, Clock::time_point now) const {
  const double seconds = std::chrono::duration<double>(now - start_).count();
  // A rate measured over a few milliseconds is noise ("500000000 layers/s" after the first band):
  // shown only once the job has run kMinRateSeconds.
  const double rate = seconds >= kMinRateSeconds && done > 0 ? done / seconds : 0.0;
  const int percent = total_ ? static_cast<int>(100.0 * done / total_) : 100;
  char buf[160];
  int n = std::snprintf(buf, sizeof buf, "%zu/%zu %s (%d%%)", done, total_, unit_.c_str(), percent);
  if (rate > 0.0) {
    n += std::snprintf(buf + n, sizeof buf - n, ", %.0f %s/s", rate, unit_.c_str());
    if (done < total_) std::snprintf(buf + n, sizeof buf - n, ", %.0f s left", std::ceil((total_ - done) / rate));
  }
  return buf;
}

void Progress::update(std::size_t done, Clock::time_point now) {
  if (mode_ == Mode::Quiet || finished_) return;
  if (mode_ == Mode::Bar) {
    // Redraw at most ~10 times a second.
    if (done != total_ && now - lastPrint_ < std::chrono::milliseconds(100)) return;
    constexpr int kWidth = 30;
    const int filled = total_ ? static_cast<int>(static_cast<double>(kWidth) * done / total_) : kWidth;
    out_ << "\r[" << std::string(filled, '#') << std::string(kWidth - filled, '.') << "] " << status(done, now)
         << "   " << std::flush;
    barShown_ = true;
  } else {
    // Logs: a line per tenth of the job, or every 10 s when a tenth takes longer.
    const int decile = total_ ? static_cast<int>(10.0 * done / total_) : 10;
    if (decile == lastDecile_ && now - lastPrint_ < std::chrono::seconds(10)) return;
    if (done == lastDone_ && lastDecile_ >= 0) return;
    lastDecile_ = decile;
    out_ << status(done, now) << '\n' << std::flush;
  }
  lastPrint_ = now;
  lastDone_ = done;
}

void Progress::finish(Clock::time_point now) {
  if (mode_ == Mode::Quiet || finished_) return;
  finished_ = true;
  const double seconds = std::chrono::duration<double>(now - start_).count();
  char buf[96];
  std::snprintf(buf, sizeof buf, "done: %zu %s in %.1f s", total_, unit_.c_str(), seconds);
  if (mode_ == Mode::Bar) out_ << '\r' << std::string(100, ' ') << '\r';
  out_ << buf << '\n' << std::flush;
}

void Progress::stop() {
  if (finished_) return;
  finished_ = true;
  if (mode_ == Mode::Bar && barShown_) out_ << '\n' << std::flush;
}

}  // namespace rodfab::cli
