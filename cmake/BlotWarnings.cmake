# Compile options shared by every Blot target (not by third-party code).
#  - warnings on, and our own code is kept warning-free;
#  - no floating-point contraction, so results do not depend on whether the
#    compiler fuses a*b+c: determinism across builds and thread counts.
add_library(blot_options INTERFACE)
#  - C++-only warnings only for C++ sources (the C API's C example and shim
#    are built with these options too).
target_compile_options(blot_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow $<$<COMPILE_LANGUAGE:CXX>:-Wnon-virtual-dtor>
  -ffp-contract=off)
if(BLOT_VALIDATE)
  target_compile_definitions(blot_options INTERFACE BLOT_VALIDATE=1)
endif()
