# rgbd_warnings: interface target every project target links to. -Werror keeps the tree clean;
# third-party headers are included as SYSTEM by their imported targets, so they do not trip it.
add_library(rgbd_warnings INTERFACE)
target_compile_options(rgbd_warnings INTERFACE
  $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Werror>
  $<$<COMPILE_LANGUAGE:C>:-Wall -Wextra -Werror>)
