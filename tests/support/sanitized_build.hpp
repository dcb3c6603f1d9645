// True in the ASan + UBSan build (tests/run-all.sh's second build, at -O0): memory figures there are the
// sanitizer's (quarantine, shadow memory) and everything runs many times slower, so tests that measure memory or
// time under heavy load check behaviour only there and leave the figures to the normal build.
#pragma once

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
}  // namespace rcand::test
