tirstrain_add_bench(fit_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/fit_bench.cpp
  LIBS tirstrain_fit)
