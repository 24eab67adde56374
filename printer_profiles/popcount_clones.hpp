// Internal to printer_profiles/: a function marked RODFAB_POPCNT_CLONES is compiled twice, with and
// without the popcount instruction, and the copy for the CPU is picked at load time (GCC's
// target_clones, common/cpu_clones.hpp). The build targets x86-64 CPUs without it, where
// std::popcount is a libgcc call per word.
#pragma once

#include "common/cpu_clones.hpp"

#define RODFAB_POPCNT_CLONES RODFAB_CLONES("popcnt", "default")
