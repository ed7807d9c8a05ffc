# find_package(yaml-cpp) for the Debian multiarch cross builds (cmake/toolchains/debian-*.cmake).
# Debian 12's libyaml-cpp-dev is not Multi-Arch: same, so the ARM build links the ARM runtime
# library libyaml-cpp0.7:<arch> and compiles against the host's headers in /usr/include/yaml-cpp
# (same source version; the headers have no architecture-specific content).
set(_rgbd_yaml_lib /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/libyaml-cpp.so.0.7)
if(NOT EXISTS ${_rgbd_yaml_lib} OR NOT EXISTS /usr/include/yaml-cpp/yaml.h)
  set(yaml-cpp_FOUND FALSE)
  set(yaml-cpp_NOT_FOUND_MESSAGE
      "need libyaml-cpp0.7:${CMAKE_LIBRARY_ARCHITECTURE} and the host's libyaml-cpp-dev (make deps)")
  return()
endif()
if(NOT TARGET yaml-cpp)
  add_library(yaml-cpp SHARED IMPORTED)
  set_target_properties(yaml-cpp PROPERTIES IMPORTED_LOCATION ${_rgbd_yaml_lib})
endif()
set(yaml-cpp_FOUND TRUE)
