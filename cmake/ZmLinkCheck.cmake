# zm_assert_not_linked(target FORBIDDEN lib...): fails the configure step if any of the forbidden
# targets is in `target`'s transitive link closure (LINK_LIBRARIES, then INTERFACE_LINK_LIBRARIES
# of every target reached). This is how "zonemapd links no simulator or harness code" is kept
# true by construction rather than by review; tests/app/zonemapd_link_test also inspects the
# binary's symbols.
function(_zm_link_closure target out_var)
  set(seen "")
  set(todo ${target})
  while(todo)
    list(POP_FRONT todo t)
    if(NOT TARGET ${t} OR t IN_LIST seen)
      continue()
    endif()
    list(APPEND seen ${t})
    get_target_property(aliased ${t} ALIASED_TARGET)
    if(aliased)
      list(APPEND todo ${aliased})
    endif()
    foreach(prop LINK_LIBRARIES INTERFACE_LINK_LIBRARIES)
      get_target_property(libs ${t} ${prop})
      if(libs)
        foreach(l ${libs})
          # Strip generator expressions such as $<LINK_ONLY:x>.
          string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" l "${l}")
          if(NOT l MATCHES "^\\$<")
            list(APPEND todo ${l})
          endif()
        endforeach()
      endif()
    endforeach()
  endwhile()
  set(${out_var} ${seen} PARENT_SCOPE)
endfunction()

function(zm_assert_not_linked target)
  cmake_parse_arguments(A "" "" "FORBIDDEN" ${ARGN})
  _zm_link_closure(${target} closure)
  foreach(f ${A_FORBIDDEN})
    if(f IN_LIST closure)
      message(FATAL_ERROR "${target} must not link ${f} (the on-device core knows nothing of the "
                          "simulator, the evaluation harness or the offline segmentation); its "
                          "link closure: ${closure}")
    endif()
  endforeach()
endfunction()
