tirstrain_add_bench(samples_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/samples_bench.cpp
  LIBS tirstrain_samples)
target_compile_definitions(samples_bench PRIVATE TIRSTRAIN_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
