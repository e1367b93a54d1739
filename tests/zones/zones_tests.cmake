# Tests of the zones module (zone files, GetZone, annotation, adjacency, splits). Included from
# tests/zones/CMakeLists.txt.
zm_add_test(zm_zones_test
  SOURCES
    ${CMAKE_CURRENT_LIST_DIR}/zone_set_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/zone_index_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/annotate_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/annotate_db_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/adjacency_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/split_test.cc
  DEPS zm_zones)
