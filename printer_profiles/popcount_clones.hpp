// Internal to printer_profiles/: a function marked RODFAB_POPCNT_CLONES is compiled twice, with and
// without the popcount instruction, and the copy for the CPU is picked at load time (GCC's
// target_clones). The build targets x86-64 CPUs without it, where std::popcount is a libgcc call per
// word. Other targets have no such clone. GCC 12 takes a call to a target_clones function to throw
// nothing: such a function must not throw.
#pragma once

#if defined(__x86_64__)
#define RODFAB_POPCNT_CLONES __attribute__((target_clones("popcnt", "default")))
#else
#define RODFAB_POPCNT_CLONES
#endif
