# poise_generate_idl(TARGET <lib> IDL_FILES <file>... [INCLUDE_DIRS <dir>...])
#
# Generates C++ types from OMG IDL with fastddsgen at BUILD time (nothing generated is committed)
# and builds two static libraries:
#   <lib>          the data types (poise::msg::State, ...) with Fast CDR (de)serialisation;
#                  vendor-neutral: links only fastcdr. Alias poise::msgs when <lib> is poise_msgs.
#   <lib>_fastdds  the fastddsgen TopicDataTypes (StatePubSubType, ...); links fastrtps. Only code
#                  that talks to Fast DDS directly (its backend, raw benchmarks) needs it.
# Output goes to ${CMAKE_BINARY_DIR}/generated/poise/msg/ so that code writes
#   #include <poise/msg/state.h>
#
# After generation, PoiseIdlBoundStrings.cmake makes every deserialiser refuse a bounded string
# longer than its bound (fastddsgen's code truncates it silently).
#
# fastddsgen flags: -cs (case-sensitive: `Header header;` would collide without it) and -replace.
# Deliberately NO -typeobject: Cyclone DDS 0.10 rejects the type information it produces, which
# breaks Cyclone <-> Fast DDS matching (see shared/design/dds-notes.md).
include_guard(GLOBAL)

find_program(POISE_FASTDDSGEN fastddsgen REQUIRED)
find_package(fastcdr REQUIRED)
find_package(fastrtps REQUIRED)

function(poise_generate_idl)
  cmake_parse_arguments(ARG "" "TARGET" "IDL_FILES;INCLUDE_DIRS" ${ARGN})
  if(NOT ARG_TARGET OR NOT ARG_IDL_FILES)
    message(FATAL_ERROR "poise_generate_idl: TARGET and IDL_FILES are required")
  endif()
  set(gen_root ${CMAKE_BINARY_DIR}/generated)
  set(out_dir ${gen_root}/poise/msg)

  set(type_sources "")
  set(type_headers "")
  set(pubsub_sources "")
  set(pubsub_headers "")
  set(idl_abs "")
  set(include_flags "")
  foreach(idl ${ARG_IDL_FILES})
    get_filename_component(abs ${idl} ABSOLUTE)
    get_filename_component(stem ${idl} NAME_WE)
    get_filename_component(dir ${abs} DIRECTORY)
    list(APPEND idl_abs ${abs})
    list(APPEND include_flags -I ${dir})
    list(APPEND type_sources ${out_dir}/${stem}.cxx)
    list(APPEND type_headers ${out_dir}/${stem}.h)
    list(APPEND pubsub_sources ${out_dir}/${stem}PubSubTypes.cxx)
    list(APPEND pubsub_headers ${out_dir}/${stem}PubSubTypes.h)
  endforeach()
  foreach(dir ${ARG_INCLUDE_DIRS})
    list(APPEND include_flags -I ${dir})
  endforeach()
  list(REMOVE_DUPLICATES include_flags)

  # One fastddsgen run for all files (the JVM start dominates). Every IDL file is a dependency of
  # every output because of #include "common.idl".
  add_custom_command(
    OUTPUT ${type_sources} ${type_headers} ${pubsub_sources} ${pubsub_headers}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${out_dir}
    COMMAND ${POISE_FASTDDSGEN} -cs -replace -d ${out_dir} ${include_flags} ${idl_abs}
    COMMAND ${CMAKE_COMMAND} "-DFILES=${type_sources}"
            -P ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/PoiseIdlBoundStrings.cmake
    DEPENDS ${idl_abs} ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/PoiseIdlBoundStrings.cmake
    COMMENT "fastddsgen: generating C++ types from ${CMAKE_CURRENT_SOURCE_DIR}/*.idl"
    VERBATIM)

  add_library(${ARG_TARGET} STATIC ${type_sources} ${type_headers})
  target_include_directories(${ARG_TARGET} PUBLIC $<BUILD_INTERFACE:${gen_root}>)
  target_link_libraries(${ARG_TARGET} PUBLIC fastcdr)
  target_compile_features(${ARG_TARGET} PUBLIC cxx_std_20)
  # Generated code: not ours to warn about.
  target_compile_options(${ARG_TARGET} PRIVATE -w)

  add_library(${ARG_TARGET}_fastdds STATIC ${pubsub_sources} ${pubsub_headers})
  target_link_libraries(${ARG_TARGET}_fastdds PUBLIC ${ARG_TARGET} fastrtps)
  target_compile_options(${ARG_TARGET}_fastdds PRIVATE -w)
endfunction()
