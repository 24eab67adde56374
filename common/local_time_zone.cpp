#include "common/local_time_zone.hpp"

#include <cstdlib>

namespace rodfab::common {

void keepLocalTimeZone() {
  ::setenv("TZ", ":/etc/localtime", 0);  // 0: a TZ already set is kept
}

}  // namespace rodfab::common
