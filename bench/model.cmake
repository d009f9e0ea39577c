tirstrain_add_bench(model_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/model_bench.cpp
  LIBS tirstrain_model)
