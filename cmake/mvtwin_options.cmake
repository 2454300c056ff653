# Compiler flags shared by every mvtwin target, applied through an interface target
# (no global include directories or flags).
add_library(mvtwin_options INTERFACE)
target_compile_options(mvtwin_options INTERFACE -Wall -Wextra -Wpedantic -Wshadow
                       -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Wunused
                       -Woverloaded-virtual -Wdouble-promotion)
if(MVTWIN_WERROR)
  target_compile_options(mvtwin_options INTERFACE -Werror)
endif()
if(MVTWIN_SANITIZE)
  target_compile_options(mvtwin_options INTERFACE -fsanitize=address,undefined
                         -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  # Stack use after scope is checked only when asked (scripts/build asan-scope): poisoning and
  # unpoisoning every small stack object (Eigen's fixed-size vectors and matrices) made the
  # simulator's tests 2-3x slower under ASan (docs/testing.md). Heap, stack-buffer and global
  # overflows, use after free and leaks are checked as before; the readers' fuzz harnesses
  # (clang) keep the scope check.
  if(NOT MVTWIN_SANITIZE_SCOPE)
    target_compile_options(mvtwin_options INTERFACE -fno-sanitize-address-use-after-scope)
  endif()
  target_link_options(mvtwin_options INTERFACE -fsanitize=address,undefined)
  # GCC documents false -Wmaybe-uninitialized positives under the sanitizers (seen in
  # libstdc++'s <regex> and Eigen at -O1): still printed, no longer fatal in this flavour.
  target_compile_options(mvtwin_options INTERFACE -Wno-error=maybe-uninitialized)
endif()
if(MVTWIN_TSAN)
  if(MVTWIN_SANITIZE)
    message(FATAL_ERROR "ThreadSanitizer and AddressSanitizer do not combine: one flavour each")
  endif()
  target_compile_options(mvtwin_options INTERFACE -fsanitize=thread -fno-omit-frame-pointer)
  target_link_options(mvtwin_options INTERFACE -fsanitize=thread)
  target_compile_options(mvtwin_options INTERFACE -Wno-error=maybe-uninitialized -Wno-error=tsan)
endif()
if(MVTWIN_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "MVTWIN_FUZZ needs clang (scripts/build fuzz chooses it)")
  endif()
  # Coverage for libFuzzer in every mvtwin object, AddressSanitizer and UBSan; the harnesses
  # link libFuzzer's main (tests/fuzz).
  target_compile_options(mvtwin_options INTERFACE -fsanitize=fuzzer-no-link,address,undefined
                         -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  target_link_options(mvtwin_options INTERFACE -fsanitize=address,undefined)
  # clang also flags float -> double in assignments, which GCC's flavours (where the warning
  # is kept for arithmetic) do not.
  target_compile_options(mvtwin_options INTERFACE -Wno-double-promotion)
endif()
