# rgbd_add_stage_subdirectories(): add every immediate sub-folder of the calling folder that has a
# CMakeLists.txt (sorted, so the order is stable). Used by onboard/, offboard/ and hil/, where each
# sub-folder is one stage, library or app.
function(rgbd_add_stage_subdirectories)
  file(GLOB subdirs LIST_DIRECTORIES true RELATIVE ${CMAKE_CURRENT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR}/*)
  list(SORT subdirs)
  foreach(dir IN LISTS subdirs)
    if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${dir}/CMakeLists.txt)
      add_subdirectory(${dir})
    endif()
  endforeach()
endfunction()
