# cmake -DNM=<nm> -DBINARY=<zonemapd> -P check_symbols.cmake
execute_process(COMMAND ${NM} -C --defined-only ${BINARY}
                OUTPUT_VARIABLE symbols RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} failed on ${BINARY} (${rc})")
endif()
string(LENGTH "${symbols}" n)
if(n LESS 1000)
  message(FATAL_ERROR "${BINARY} shows almost no symbols: is it stripped? (the check needs them)")
endif()
# The simulator, the harness, and the offline segmentation (lib/segment).
set(forbidden "zm::sim::" "zm::CotenantProcess" "zm::DeviceLedger" "zm::RunScenario"
              "zm::RunOnDevice" "zm::ExperimentProfile" "zm::LoadExperimentProfile"
              "zm::SegmentRooms" "zm::CutPieces" "zm::MergeLayoutPieces" "zm::LoadOccupancyGrid"
              "zm::FindWalls" "zm::ScoreSegmentation")
foreach(f ${forbidden})
  string(FIND "${symbols}" "${f}" at)
  if(NOT at EQUAL -1)
    string(SUBSTRING "${symbols}" ${at} 160 context)
    message(FATAL_ERROR "zonemapd defines '${f}' (simulator, harness or segmentation code): "
                        "${context}")
  endif()
endforeach()
message(STATUS "zonemapd: no simulator, harness or segmentation symbols among ${n} bytes of "
               "symbols")
