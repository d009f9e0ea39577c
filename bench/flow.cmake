# Feature tracking: speed against error, both presets and a parameter sweep in one table.
if(TARGET tirstrain_flow AND TARGET tirstrain_samples)
  tirstrain_add_bench(flow_bench
    SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/flow_bench.cpp ${PROJECT_SOURCE_DIR}/tests/flow/flow_support.cpp
    LIBS tirstrain_flow tirstrain_samples tirstrain_studies)
endif()
