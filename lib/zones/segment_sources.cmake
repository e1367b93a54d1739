# Sources of zm_zones owned by the segmentation work (issue 10): occupancy grids and automatic
# zones from them or from keyframes, and their scoring. Included from lib/zones/CMakeLists.txt.
set(ZM_ZONES_SEGMENT_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/declutter.cc
  ${CMAKE_CURRENT_LIST_DIR}/grid_map.cc
  ${CMAKE_CURRENT_LIST_DIR}/layout_merge.cc
  ${CMAKE_CURRENT_LIST_DIR}/segmentation.cc
)
