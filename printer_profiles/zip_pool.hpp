// libzip archive handles are not thread-safe: readers that serve several threads borrow one handle
// each from a ZipPool, which opens another when none is free. Internal to printer_profiles/ (the job
// readers of job_files.cpp and job_reader.cpp).
#pragma once

#include <zip.h>

#include <functional>
#include <mutex>
#include <vector>

namespace rodfab::printer_profiles {

class ZipPool {
public:
  // `open` opens one more handle on the archive (or throws); called with no lock held.
  explicit ZipPool(std::function<zip_t*()> open) : open_(std::move(open)) {}
  ~ZipPool();  // discards every handle handed back
  ZipPool(const ZipPool&) = delete;
  ZipPool& operator=(const ZipPool&) = delete;

  // A free handle, or a new one from `open`: the caller's alone until it gives it back.
  zip_t* borrow() const;
  // Hands `za` (borrowed, or opened by the owner) to the pool, which discards it when destroyed.
  void giveBack(zip_t* za) const;

  // A handle borrowed for one scope, given back when the scope ends (exceptions included).
  class Lease {
  public:
    explicit Lease(const ZipPool& pool) : pool_(pool), za_(pool.borrow()) {}
    ~Lease() { pool_.giveBack(za_); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    zip_t* get() const { return za_; }

  private:
    const ZipPool& pool_;
    zip_t* za_;
  };

private:
  std::function<zip_t*()> open_;
  mutable std::mutex mutex_;
  mutable std::vector<zip_t*> free_;
};

}  // namespace rodfab::printer_profiles
