// The local time zone read once per process instead of once per time conversion.
#pragma once

namespace rodfab::common {

// libzip converts each entry's DOS time with mktime (about ten calls an entry as a job's zip is built
// and verified), and glibc's mktime, while TZ is unset, checks its default zone file /etc/localtime
// with a stat() system call every time in case it changed: 60,000 calls for a 6,000-layer job, on the
// writer's serial tail (about a sixth of the spring's tail on the benchmark machine, bench/README.md
// "The writer's tail"). With TZ set to that same file (":/etc/localtime", glibc's own default) glibc
// reads it once and keeps it; times and zone are what they were. Does nothing when TZ is set.
// Not thread-safe (setenv): call it first thing in main(), before any thread starts.
void keepLocalTimeZone();

}  // namespace rodfab::common
