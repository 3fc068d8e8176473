# Shared compile settings, applied per target (house style: no directory-wide flags).
function(poise_target_defaults target)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  target_compile_features(${target} PUBLIC cxx_std_20)
  # poise/cli/parse.hpp (POISE_CLI_PARSE: a usage error exits 2), header-only
  target_include_directories(${target} PRIVATE ${PROJECT_SOURCE_DIR}/components/cli/include)
endfunction()

# poise_add_gtest(NAME SOURCES... [LIBS ...] [LABELS ...] [TIMEOUT s] [RUN_SERIAL])
# Builds one GoogleTest executable and registers its tests with ctest. RUN_SERIAL: its tests run
# alone under ctest -j (real-time tests whose verdict depends on having the cores).
function(poise_add_gtest name)
  cmake_parse_arguments(ARG "RUN_SERIAL" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES} ${ARG_UNPARSED_ARGUMENTS})
  poise_target_defaults(${name})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE POISE_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                                             POISE_BINARY_DIR="${PROJECT_BINARY_DIR}")
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/tests)
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  set(serial FALSE)
  if(ARG_RUN_SERIAL)
    set(serial TRUE)
  endif()
  # Labels go on the directory (ctest gives every test in it the directory's LABELS): passed
  # through gtest_discover_tests, a list "a;b" is split into separate arguments, so that
  # "LABELS a b RUN_SERIAL TRUE" sets LABELS=a and b=RUN_SERIAL, and RUN_SERIAL is lost.
  set_property(DIRECTORY APPEND PROPERTY LABELS ${ARG_LABELS})
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT} RUN_SERIAL ${serial})
endfunction()

# poise_register_cli_command(VERB SUMMARY FUNCTION LIBRARY)
# Makes `poise VERB ...` call `int FUNCTION(int argc, char** argv)` (argv[0] is "poise VERB"),
# linking LIBRARY into the `poise` tool. Areas call this from their own CMakeLists.txt, so that
# no shared file needs editing when a verb is added.
function(poise_register_cli_command verb summary function library)
  set_property(GLOBAL APPEND PROPERTY POISE_CLI_VERBS "${verb}")
  set_property(GLOBAL PROPERTY POISE_CLI_${verb}_SUMMARY "${summary}")
  set_property(GLOBAL PROPERTY POISE_CLI_${verb}_FUNCTION "${function}")
  set_property(GLOBAL PROPERTY POISE_CLI_${verb}_LIBRARY "${library}")
endfunction()

# poise_add_area_modules()
# Adds every sub-folder of the current area folder that has a CMakeLists.txt, alphabetically, so
# that a new module never needs a shared file edited. components/cli is added by the top level,
# after every area (it links them all).
function(poise_add_area_modules)
  file(GLOB children RELATIVE ${CMAKE_CURRENT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR}/*)
  list(SORT children)
  foreach(child ${children})
    if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${child}/CMakeLists.txt
       AND NOT (child STREQUAL "cli" AND CMAKE_CURRENT_SOURCE_DIR STREQUAL "${PROJECT_SOURCE_DIR}/components"))
      add_subdirectory(${child})
    endif()
  endforeach()
endfunction()
