// RODFAB_CLONES("avx2", "default"): the function is compiled once per listed CPU feature level and
// the copy for the CPU is picked when the library loads (GCC's target_clones, an ifunc). Every user
// makes each clone compute the same bits as the baseline (its comment says how). GCC 12 takes a call
// to a target_clones function to throw nothing: such a function must not throw.
// GCC on x86-64 only: other targets have no such levels, and clang's sanitizers (the fuzz builds)
// instrument the ifunc resolvers, which run before the sanitizer runtime is ready: every fuzz target
// loading a library with clones crashed before its first input.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define RODFAB_CLONES(...) __attribute__((target_clones(__VA_ARGS__)))
// Code written for one feature level (gnu::target("avx2")) is compiled: GCC on x86-64. Clang refuses
// such code where vectors wider than the baseline's pass between functions (each lambda is a function
// of the baseline to it: "AVX vector argument ... changes the ABI"), so its builds keep the baseline.
#define RODFAB_TARGET_PATHS 1
#else
#define RODFAB_CLONES(...)
#define RODFAB_TARGET_PATHS 0
#endif
