# Precompiled headers. Every translation unit parses Eigen, and many parse nlohmann/json, CLI11
# and GoogleTest again: 2-9 s per file and header at -O2, more than half of the compile time
# of a command or a test file (measured on 2 cores: the test flavour's 173 files took 33 min
# of CPU). Each library precompiles them once for its own files (its own flags: forward
# builds with OpenMP and EIGEN_DONT_PARALLELIZE); the test programs, one file each, share one
# precompiled header (mvtwin_test_pch in tests/CMakeLists.txt).
#
# A precompiled header is included before every file, so it can hide a missing #include: the
# release flavour (scripts/build release) builds without them and catches that.
option(MVTWIN_PCH "Precompile the heavy third-party headers (faster builds)" ON)

# Unity builds: each library's (and the commands') files compiled a few to a translation unit.
# The precompiled header saves parsing; what is left is instantiating and optimizing the same
# templates (nlohmann/json, CLI11, Eigen) again in every file. Measured under ASan + UBSan at
# -O1 (docs/testing.md): the commands' 26 files took 650 s of CPU one by one, 91 s as one unit.
# Batches of MVTWIN_UNITY_BATCH files keep both cores busy. Like the precompiled header, a
# unity build can hide a missing #include, or a file that leans on another's `using`: the
# release flavour builds file by file and catches those. It refuses two private helpers of one
# name in a library; the ones it found were copies, now written once (core/stopwatch.h,
# core/nan.h, raw::trim, raw::format_number).
# The test programs batch their files the same way (tests/CMakeLists.txt).
option(MVTWIN_UNITY "Compile each library's files a few to a translation unit" ON)
set(MVTWIN_UNITY_BATCH 8 CACHE STRING "Files per unity translation unit")

set(MVTWIN_PCH_STD <algorithm> <array> <cmath> <cstdint> <filesystem> <functional> <map>
    <memory> <optional> <sstream> <stdexcept> <string> <utility> <vector>)

# mvtwin_precompile(target header...): the standard headers above, Eigen/Dense and the
# given headers, precompiled for the target's own files; and the target's files in unity
# batches (MVTWIN_UNITY).
function(mvtwin_precompile target)
  if(MVTWIN_UNITY)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON
                          UNITY_BUILD_BATCH_SIZE ${MVTWIN_UNITY_BATCH})
  endif()
  if(MVTWIN_PCH)
    target_precompile_headers(${target} PRIVATE ${MVTWIN_PCH_STD} <Eigen/Dense> ${ARGN})
  endif()
endfunction()
