# ASan + UBSan for the whole configuration when RGBD_SANITIZE=ON (`make test` builds the
# protocol library and its tests this way in build-asan/). Any UB report aborts the test.
if(RGBD_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined)
endif()

# rgbd_add_fuzzer(name source... LINK libs...): a libFuzzer target, only when RGBD_FUZZ=ON.
function(rgbd_add_fuzzer name)
  if(NOT RGBD_FUZZ)
    return()
  endif()
  cmake_parse_arguments(F "" "" "LINK" ${ARGN})
  add_executable(${name} ${F_UNPARSED_ARGUMENTS})
  target_compile_options(${name} PRIVATE -fsanitize=fuzzer,address,undefined)
  target_link_options(${name} PRIVATE -fsanitize=fuzzer,address,undefined)
  target_link_libraries(${name} PRIVATE ${F_LINK} rgbd_warnings)
endfunction()
