# Contact segmentation: ms/frame at 640x512 and 1280x1024, full and reduced resolution, next to mask IoU.
if(TARGET tirstrain_contact)
  tirstrain_add_bench(contact_bench
    SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/contact_bench.cpp
    LIBS tirstrain_contact)
endif()

# The segmenter's ellipse-centre error next to the feasible range of the truth's centre (what the frame shows).
if(TARGET tirstrain_pipeline)
  add_executable(contact_observability_bench ${CMAKE_CURRENT_SOURCE_DIR}/contact_observability_bench.cpp)
  target_link_libraries(contact_observability_bench PRIVATE tirstrain_pipeline tirstrain_flags)
endif()
