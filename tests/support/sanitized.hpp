#pragma once
// Smaller frames and fewer repetitions for the slowest tests in the
// ASan+UBSan build. tests/CMakeLists.txt defines CELLRAY_TEST_SANITIZED when
// CELLRAY_SANITIZE is ON. The sanitizers need every code path to run, not
// many pixels: the same test cases and assertions run there on less work,
// and the Release build runs the full sizes on every ISA.

namespace cellray::test {

/// True in the sanitizer build.
#ifdef CELLRAY_TEST_SANITIZED
inline constexpr bool sanitized = true;
#else
inline constexpr bool sanitized = false;
#endif

/// `full` in the Release build, `reduced` in the sanitizer build. Use it for
/// frame sizes and repetition counts whose assertions hold at both (bounds
/// stated as fractions, with a margin the smaller size still keeps).
constexpr int full_or_sanitized(int full, int reduced) { return sanitized ? reduced : full; }

}  // namespace cellray::test
