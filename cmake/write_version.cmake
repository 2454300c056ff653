# Script mode (cmake -P): writes the version header from `git describe`.
set(describe "unknown")
find_package(Git QUIET)
if(GIT_FOUND)
  execute_process(COMMAND ${GIT_EXECUTABLE} describe --always --dirty --abbrev=12
                  WORKING_DIRECTORY ${SOURCE_DIR} OUTPUT_VARIABLE out
                  OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE rc ERROR_QUIET)
  if(rc EQUAL 0)
    set(describe "${out}")
  endif()
endif()
set(MVTWIN_VERSION_STRING "${PROJECT_VERSION}+${describe}")
configure_file(${SOURCE_DIR}/cmake/version.h.in ${OUTPUT} @ONLY)
