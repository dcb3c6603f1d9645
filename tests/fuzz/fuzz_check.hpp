// Invariant checks for the fuzz targets: a broken invariant is a crash libFuzzer records (with the input), whatever
// NDEBUG says. Messages never print the input itself (it may hold a token).
#pragma once

#include <cstdio>
#include <cstdlib>

#define RCAND_FUZZ_CHECK(condition, what)                                                             \
  do {                                                                                                \
    if (!(condition)) {                                                                               \
      std::fprintf(stderr, "fuzz invariant broken at %s:%d: %s (%s)\n", __FILE__, __LINE__, (what), #condition); \
      std::abort();                                                                                   \
    }                                                                                                 \
  } while (false)
