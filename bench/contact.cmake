# Contact segmentation: ms/frame at 640x512 and 1280x1024, full and reduced resolution, next to mask IoU.
if(TARGET tirstrain_contact)
  tirstrain_add_bench(contact_bench
    SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/contact_bench.cpp
    LIBS tirstrain_contact)
endif()
