# The viewer's ctest, included by tests/CMakeLists.txt when blot-viewer is built.
# Under Xvfb with Mesa's software GL (~20 s on 2 cores): label `viewer`, which
# scripts/test runs (it excludes only `study` and `client`); alone:
# `ctest --test-dir build -L viewer`.
add_test(NAME viewer_two_way_flag_drop
         COMMAND ${PROJECT_SOURCE_DIR}/demos/viewer/viewer_test.sh $<TARGET_FILE:blot-viewer>
                 $<TARGET_FILE:blot_viewer_stain_pixels> ${PROJECT_SOURCE_DIR}/assets/scenes/two_way_flag.json
                 ${PROJECT_BINARY_DIR}/demos/viewer/viewer_test)
set_tests_properties(viewer_two_way_flag_drop PROPERTIES LABELS viewer TIMEOUT 300)
# Its script options, checked before any window opens (no display needed):
# a frame count past int (3e9 read as "--exit needs --frames N") and a drop
# after the last frame (skipped silently before) are refused; --help exits 0.
add_test(NAME viewer_refuses_a_frame_count_past_int COMMAND blot-viewer --frames 3e9 --exit)
set_tests_properties(viewer_refuses_a_frame_count_past_int PROPERTIES LABELS unit
                     PASS_REGULAR_EXPRESSION "--frames must be a whole number in \\[0, 10000000\\]")
add_test(NAME viewer_refuses_a_drop_after_the_last_frame COMMAND blot-viewer --frames 2 --exit --drop 0.5,0.4@5)
set_tests_properties(viewer_refuses_a_drop_after_the_last_frame PROPERTIES LABELS unit
                     PASS_REGULAR_EXPRESSION "--drop @5 is after the last frame \\(--frames 2\\)")
add_test(NAME viewer_help COMMAND blot-viewer --help)
set_tests_properties(viewer_help PROPERTIES LABELS unit PASS_REGULAR_EXPRESSION "usage: blot-viewer")
