#include "common/local_time_zone.hpp"

#include <cstdlib>

namespace rodfab::common {

void keepLocalTimeZone() {
  if (std::getenv("TZ") == nullptr) ::setenv("TZ", ":/etc/localtime", 0);
}

}  // namespace rodfab::common
