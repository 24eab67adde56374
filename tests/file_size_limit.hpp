// Test helpers: a scope in which no file of the process grows past a size (a full disk, as write()
// sees it: EFBIG instead of ENOSPC), and the signal disposition and soft limit it sets, restored after.
#pragma once

#include <catch2/catch.hpp>

#include <sys/resource.h>

#include <csignal>

namespace rodfab::test {

// Sets `signal`'s disposition (sigaction) for the scope and restores the one before, whatever leaves it.
class SignalDisposition {
public:
  SignalDisposition(int signal, void (*handler)(int)) : signal_(signal) {
    struct sigaction wanted {};
    wanted.sa_handler = handler;
    sigemptyset(&wanted.sa_mask);
    REQUIRE(::sigaction(signal_, &wanted, &saved_) == 0);
  }
  ~SignalDisposition() { ::sigaction(signal_, &saved_, nullptr); }
  SignalDisposition(const SignalDisposition&) = delete;
  SignalDisposition& operator=(const SignalDisposition&) = delete;

private:
  int signal_;
  struct sigaction saved_ {};
};

// Sets the soft limit of `resource` for the scope (the hard one stays) and restores the one before.
class SoftLimit {
public:
  SoftLimit(int resource, rlim_t soft) : resource_(resource) {
    REQUIRE(::getrlimit(resource_, &saved_) == 0);
    rlimit lowered = saved_;
    lowered.rlim_cur = soft;
    REQUIRE(::setrlimit(resource_, &lowered) == 0);
  }
  ~SoftLimit() { ::setrlimit(resource_, &saved_); }
  SoftLimit(const SoftLimit&) = delete;
  SoftLimit& operator=(const SoftLimit&) = delete;

private:
  int resource_;
  rlimit saved_{};
};

// No file of the process may grow past `bytes` in the scope: soft RLIMIT_FSIZE with SIGXFSZ ignored, so
// write() fails with EFBIG (on any thread) instead of the signal killing the process. Both are restored
// when the scope ends, also by an exception (a failed REQUIRE); the disposition is set first and
// restored last, so the limit never holds while SIGXFSZ would kill.
struct FileSizeLimit {
  explicit FileSizeLimit(rlim_t bytes) : limit{RLIMIT_FSIZE, bytes} {}
  SignalDisposition ignoreXfsz{SIGXFSZ, SIG_IGN};
  SoftLimit limit;
};

// No file of the process may grow at all in the scope.
struct NoFileGrowth : FileSizeLimit {
  NoFileGrowth() : FileSizeLimit(0) {}
};

}  // namespace rodfab::test
