# Automatic zones (issue 10): grid loaders, room segmentation, keyframe-only zones, scoring.
# Included from tests/zones/CMakeLists.txt.
zm_add_test(zm_segment_test SOURCES ${CMAKE_CURRENT_LIST_DIR}/segmentation_test.cc DEPS zm_zones)
zm_add_test(zm_declutter_test SOURCES ${CMAKE_CURRENT_LIST_DIR}/declutter_test.cc DEPS zm_zones)
zm_add_test(zm_layout_merge_test SOURCES ${CMAKE_CURRENT_LIST_DIR}/layout_merge_test.cc
            DEPS zm_zones)
