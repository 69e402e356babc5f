# The viewer's ctest, included by tests/CMakeLists.txt when blot-viewer is built.
# Under Xvfb with Mesa's software GL (~20 s on 2 cores): label `viewer`, which
# scripts/test skips; run it with `ctest --test-dir build -L viewer`.
add_test(NAME viewer_two_way_flag_drop
         COMMAND ${PROJECT_SOURCE_DIR}/demos/viewer/viewer_test.sh $<TARGET_FILE:blot-viewer>
                 $<TARGET_FILE:blot_viewer_stain_pixels> ${PROJECT_SOURCE_DIR}/assets/scenes/two_way_flag.json
                 ${PROJECT_BINARY_DIR}/demos/viewer/viewer_test)
set_tests_properties(viewer_two_way_flag_drop PROPERTIES LABELS viewer TIMEOUT 300)
