// True in the ASan + UBSan build (tests/run-all.sh's second build, at -O0): memory figures there are the
// sanitizer's (quarantine, shadow memory) and everything runs many times slower, so tests that measure memory or
// time under heavy load check behaviour only there and leave the figures to the normal build.
#pragma once

#include <string>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#define RCAND_TEST_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RCAND_TEST_SANITIZED 1
#endif
#endif

namespace rcand::test {
#ifdef RCAND_TEST_SANITIZED
inline constexpr bool kSanitizedBuild = true;
#else
inline constexpr bool kSanitizedBuild = false;
#endif

// rcanctl's stop and swarm stop wait 400 ms by default, which an -O0 ASan rcand on a loaded machine can miss: in
// the sanitizer build they get 5 s; the normal build keeps the default.
inline std::vector<std::string> with_stop_timeout(std::vector<std::string> args) {
  if (kSanitizedBuild) args.insert(args.end(), {"--timeout", "5000"});
  return args;
}
}  // namespace rcand::test
