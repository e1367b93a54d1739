# Sources of zm_zones (zone files, index, annotation, adjacency, splits). Included from
# lib/zones/CMakeLists.txt.
set(ZM_ZONES_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/polygon.cc
  ${CMAKE_CURRENT_LIST_DIR}/zone_set.cc
  ${CMAKE_CURRENT_LIST_DIR}/zone_index.cc
  ${CMAKE_CURRENT_LIST_DIR}/principal_axis.cc
  ${CMAKE_CURRENT_LIST_DIR}/split.cc
  ${CMAKE_CURRENT_LIST_DIR}/annotate.cc
  ${CMAKE_CURRENT_LIST_DIR}/adjacency.cc
)
