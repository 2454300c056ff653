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

set(MVTWIN_PCH_STD <algorithm> <array> <cmath> <cstdint> <filesystem> <functional> <map>
    <memory> <optional> <sstream> <stdexcept> <string> <utility> <vector>)

# mvtwin_precompile(target header...): the standard headers above, Eigen/Dense and the
# given headers, precompiled for the target's own files.
function(mvtwin_precompile target)
  if(MVTWIN_PCH)
    target_precompile_headers(${target} PRIVATE ${MVTWIN_PCH_STD} <Eigen/Dense> ${ARGN})
  endif()
endfunction()
