# The version string recorded in every result file: project version plus the git commit
# (with -dirty when the tree had uncommitted changes at configure time).
set(MVTWIN_GIT_DESCRIBE "unknown")
find_package(Git QUIET)
if(GIT_FOUND)
  execute_process(COMMAND ${GIT_EXECUTABLE} describe --always --dirty --abbrev=12
                  WORKING_DIRECTORY ${CMAKE_SOURCE_DIR}
                  OUTPUT_VARIABLE _describe OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE _rc ERROR_QUIET)
  if(_rc EQUAL 0)
    set(MVTWIN_GIT_DESCRIBE "${_describe}")
  endif()
endif()
set(MVTWIN_VERSION_STRING "${PROJECT_VERSION}+${MVTWIN_GIT_DESCRIBE}")
configure_file(${CMAKE_SOURCE_DIR}/cmake/version.h.in
               ${CMAKE_BINARY_DIR}/generated/mvtwin/core/version.h @ONLY)
