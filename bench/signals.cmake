tirstrain_add_bench(signals_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/signals_bench.cpp
  LIBS tirstrain_signals)
