#pragma once
// Smaller models for the tests that simulate, render or train, where that work runs several
// times slower: under AddressSanitizer + UBSan (docs/testing.md). Those tests check code paths
// (resuming, refusing, writing, classifying), which do not depend on the grid, and the test
// flavour runs them at their usual size. MVTWIN_TEST_SMALL=1 makes any build use the small
// models (the way to see that they still pass the tests' assertions without waiting for a
// sanitizer build), MVTWIN_TEST_SMALL=0 the usual ones (to time both in one build).
#include <cstdlib>
#include <cstring>

namespace mvtwin::test_support {

inline bool small_models() {
  const char* e = std::getenv("MVTWIN_TEST_SMALL");
  if (e != nullptr && std::strcmp(e, "1") == 0) return true;
  if (e != nullptr && std::strcmp(e, "0") == 0) return false;
#ifdef __SANITIZE_ADDRESS__
  return true;
#else
  return false;
#endif
}

}  // namespace mvtwin::test_support
