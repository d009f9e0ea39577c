tirstrain_add_bench(capture_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/capture_bench.cpp
  LIBS tirstrain_capture)
