# Measured studies kept for their benchmark rows, not used by the pipeline (bench/studies/README.md).
if(TARGET tirstrain_flow)
  add_library(tirstrain_studies STATIC ${CMAKE_CURRENT_SOURCE_DIR}/studies/mesh_correlation.cpp)
  target_link_libraries(tirstrain_studies PUBLIC tirstrain_flow PRIVATE tirstrain_flags)
  if(TIRSTRAIN_BUILD_TESTS)
    tirstrain_add_gtest(studies_tests
      SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/studies/mesh_correlation_test.cpp
      LIBS tirstrain_studies
      LABELS flow)
  endif()
endif()
