tirstrain_add_bench(strain_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/strain_bench.cpp
  LIBS tirstrain_strain)
