// libxxhash's XXH3 functions as the runtime-dispatched ones on x86 (its xxh_x86dispatch.h: AVX2 or
// AVX-512 where the processor has them, SSE2 otherwise; the same hashes). The plain entry points are
// the library's SSE2 build: 16-20 GB/s against 41-46 GB/s dispatched, hashing 256 KiB images on this
// project's machine (the manifest hashes every layer image of a job). Include instead of <xxhash.h>.
#pragma once

#include <xxhash.h>

#if (defined(__x86_64__) || defined(__i386__)) && __has_include(<xxh_x86dispatch.h>)
#include <xxh_x86dispatch.h>
#endif
