#include "printer_profiles/zip_pool.hpp"

namespace rodfab::printer_profiles {

ZipPool::~ZipPool() {
  for (zip_t* za : free_) zip_discard(za);
}

zip_t* ZipPool::borrow() const {
  {
    std::lock_guard lock(mutex_);
    if (!free_.empty()) {
      zip_t* za = free_.back();
      free_.pop_back();
      return za;
    }
  }
  return open_();
}

void ZipPool::giveBack(zip_t* za) const {
  std::lock_guard lock(mutex_);
  free_.push_back(za);
}

}  // namespace rodfab::printer_profiles
