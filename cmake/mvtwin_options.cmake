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
  # libstdc++'s own checks (an index past a vector's end, front() of an empty one): cheap, and
  # they catch what UBSan's null check caught in this code.
  target_compile_definitions(mvtwin_options INTERFACE _GLIBCXX_ASSERTIONS)
  # The full checks only when asked (MVTWIN_SANITIZE_FULL, scripts/build asan-full); they double
  # the build and slow the tests (docs/testing.md):
  # - stack use after scope: poisoning and unpoisoning every small stack object (Eigen's
  #   fixed-size vectors and matrices) made the simulator's tests 2-3x slower under ASan;
  # - UBSan's checks of every pointer use (null, alignment, object size, pointer overflow, the
  #   dynamic type of polymorphic objects, nonnull attributes): about 40 % of the compile time of
  #   Eigen-heavy files (the simulator's unity unit 83 -> 46 s); ASan and the assertions above
  #   cover most of what they catch (a null dereference is a crash ASan reports, Eigen asserts
  #   alignment itself). Integer overflow, shifts, bounds, division by zero, bool and enum
  #   values, missing returns and unreachable code stay checked.
  # Heap, stack-buffer and global overflows, use after free and leaks are checked as before; the
  # readers' fuzz harnesses (clang) keep every check.
  if(NOT MVTWIN_SANITIZE_FULL)
    target_compile_options(mvtwin_options INTERFACE -fno-sanitize-address-use-after-scope
        -fno-sanitize=vptr,null,alignment,object-size,pointer-overflow,nonnull-attribute,returns-nonnull-attribute)
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
