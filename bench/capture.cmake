tirstrain_add_bench(capture_bench
  SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/capture_bench.cpp
  LIBS tirstrain_capture)

# A fast fake GigE Vision camera (Aravis' ArvGvFakeCamera serving pre-rendered frames) for
# bench/capture_record_bench.sh and bench/capture_live_latency_bench.sh. Not a Google Benchmark program.
add_executable(tirstrain_fake_camera ${CMAKE_CURRENT_SOURCE_DIR}/fake_camera.cpp)
target_link_libraries(tirstrain_fake_camera PRIVATE PkgConfig::ARAVIS tirstrain_opencv tirstrain_flags)
