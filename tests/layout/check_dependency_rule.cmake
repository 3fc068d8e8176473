cmake_minimum_required(VERSION 3.25)
# ctest layout_dependency_rule: fails, naming each offence, when code under the areas
# (components/, estimator/, controller/, simulator/) depends on deploy/.
#   cmake -DSOURCE_DIR=... -DGRAPH=layout_graph.txt -DAREAS="components;..." -P this file
# GRAPH (written by tests/layout/CMakeLists.txt at configure time) has one line per edge:
#   link TARGET DEPENDENCY DEPENDENCY_SOURCE_DIR   |   include TARGET INCLUDE_DIRECTORY
set(_deploy "${SOURCE_DIR}/deploy")
set(_bad "")

# 1. Targets: a deploy/ library linked, a deploy/ include directory.
file(STRINGS "${GRAPH}" _edges)
foreach(_e ${_edges})
  string(REPLACE " " ";" _f "${_e}")
  list(GET _f 0 _kind)
  list(GET _f 1 _target)
  list(GET _f 2 _what)
  if(_kind STREQUAL "link")
    list(GET _f 3 _dir)
    if(_dir STREQUAL _deploy OR _dir MATCHES "^${_deploy}/")
      string(APPEND _bad "  target ${_target} links ${_what}, a library of ${_dir}\n")
    endif()
  elseif(_what STREQUAL _deploy OR _what MATCHES "^${_deploy}/")
    string(APPEND _bad "  target ${_target} has the include directory ${_what}\n")
  endif()
endforeach()

# 2. Sources: an #include of a header that deploy/ provides (paths under any include/ folder of
# deploy/, e.g. poise/launch/launch.hpp), or of a path naming deploy/.
file(GLOB_RECURSE _headers RELATIVE "${_deploy}" "${_deploy}/*.hpp" "${_deploy}/*.h")
set(_provided "")
foreach(_h ${_headers})
  if(_h MATCHES "(^|/)include/(.+)$")
    list(APPEND _provided "${CMAKE_MATCH_2}")
  endif()
endforeach()
set(_n_files 0)
foreach(_area ${AREAS})
  file(GLOB_RECURSE _files "${SOURCE_DIR}/${_area}/*.cpp" "${SOURCE_DIR}/${_area}/*.hpp"
       "${SOURCE_DIR}/${_area}/*.h" "${SOURCE_DIR}/${_area}/*.c" "${SOURCE_DIR}/${_area}/*.cc"
       "${SOURCE_DIR}/${_area}/*.in")
  foreach(_file ${_files})
    math(EXPR _n_files "${_n_files} + 1")
    file(STRINGS "${_file}" _includes REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
    foreach(_line ${_includes})
      if(_line MATCHES "include[ \t]*[<\"]([^>\"]+)[>\"]")
        set(_inc "${CMAKE_MATCH_1}")
        if(_inc IN_LIST _provided OR _inc MATCHES "(^|/)deploy/")
          file(RELATIVE_PATH _rel "${SOURCE_DIR}" "${_file}")
          string(APPEND _bad "  ${_rel} includes ${_inc} (deploy/)\n")
        endif()
      endif()
    endforeach()
  endforeach()
endforeach()

list(LENGTH _edges _n_edges)
list(LENGTH _provided _n_headers)
if(_n_edges EQUAL 0 OR _n_files EQUAL 0 OR _n_headers EQUAL 0)
  message(FATAL_ERROR "layout rule: nothing to check (${_n_edges} target edges, ${_n_files} "
                      "source files, ${_n_headers} deploy/ headers): the check itself is broken")
endif()
if(_bad)
  message(FATAL_ERROR "layout rule broken: nothing under ${AREAS} may depend on deploy/ "
                      "(README.md, Layout):\n${_bad}")
endif()
message(STATUS "layout rule holds: ${_n_edges} target edges and ${_n_files} source files of "
               "${AREAS} checked against ${_n_headers} deploy/ headers")
