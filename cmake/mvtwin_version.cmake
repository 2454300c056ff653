# The version string recorded in every result file: project version plus the git commit (with
# -dirty when the tree has uncommitted changes). Regenerated at every build, and rewritten only
# when it changes, so provenance never names a stale commit.
set(MVTWIN_VERSION_HEADER ${CMAKE_BINARY_DIR}/generated/mvtwin/core/version.h)
add_custom_target(mvtwin_version
  COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${CMAKE_SOURCE_DIR} -DOUTPUT=${MVTWIN_VERSION_HEADER}
          -DPROJECT_VERSION=${PROJECT_VERSION} -P ${CMAKE_SOURCE_DIR}/cmake/write_version.cmake
  BYPRODUCTS ${MVTWIN_VERSION_HEADER}
  COMMENT "mvtwin version header")
