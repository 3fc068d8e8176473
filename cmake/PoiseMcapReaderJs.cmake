# poise_add_mcap_reader_js([SELFTEST_TEST <name>])
#
# Sets up the independent MCAP reader that the recorder tests use to check every recorded file:
# tests/record/mcap_reader_js/mcap_check.mjs, a Node.js script on the official npm packages
# @mcap/core, @mcap/support, @foxglove/omgidl-parser and @foxglove/omgidl-serialization (versions
# pinned in package.json / package-lock.json next to it). Nothing of it is shared with the C++
# recorder.
#
# Usage (e.g. in tests/CMakeLists.txt, before the tests that need it):
#   include(PoiseMcapReaderJs)
#   poise_add_mcap_reader_js(SELFTEST_TEST mcap_reader_js_selftest)   # SELFTEST_TEST optional
#   add_test(NAME record_check COMMAND ${POISE_MCAP_CHECK} --streaming ${out}/run.mcap)
#
# What it does:
#   - finds `node` (>= 18) and `npm`; if either is missing, configuring stops with an error that
#     says to install them (deploy/bootstrap.sh installs Debian's nodejs and npm).
#   - adds the target `poise_mcap_reader_js` (part of ALL): copies package.json,
#     package-lock.json and the *.mjs scripts to ${CMAKE_BINARY_DIR}/mcap_reader_js/ and runs
#     `npm ci --no-audit --no-fund --ignore-scripts` there. npm ci runs again only when
#     package.json or package-lock.json change (stamp file npm-ci.stamp); a changed script is just
#     copied again. The first build needs the npm registry (or a warm npm cache); no package needs
#     an install script.
#   - sets, in the cache (INTERNAL, so visible in every directory) and in the caller's scope:
#       POISE_MCAP_CHECK      command prefix: <node>;<build>/mcap_reader_js/mcap_check.mjs
#                             append [--streaming] [--dump OUT.jsonl] FILE.mcap. It prints one JSON
#                             report; exit 0 = all messages decoded (and, indexed, file complete),
#                             1 = a check failed, 2 = usage error / not an MCAP file.
#       POISE_MCAP_SELFTEST   command of the checker's self-test (selftest.mjs): writes MCAP files
#                             of Poise types with @mcap/core's writer and checks mcap_check.mjs on
#                             them, no recorder or DDS needed (~1 min).
#       POISE_MCAP_READER_JS_TARGET  poise_mcap_reader_js (for add_dependencies / FIXTURES).
#   - SELFTEST_TEST <name>: also registers POISE_MCAP_SELFTEST as a CTest test <name> (label
#     "record").
#
# Tests that run the checker need the target built first: `cmake --build` (ALL) does it.
include_guard(GLOBAL)

cmake_path(GET CMAKE_CURRENT_LIST_DIR PARENT_PATH POISE_MCAP_READER_JS_ROOT) # the source tree
set(POISE_MCAP_READER_JS_SOURCE_DIR ${POISE_MCAP_READER_JS_ROOT}/tests/record/mcap_reader_js)

function(poise_add_mcap_reader_js)
  cmake_parse_arguments(ARG "" "SELFTEST_TEST" "" ${ARGN})
  if(ARG_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "poise_add_mcap_reader_js: unknown arguments ${ARG_UNPARSED_ARGUMENTS}")
  endif()
  if(TARGET poise_mcap_reader_js)
    message(FATAL_ERROR "poise_add_mcap_reader_js: called twice")
  endif()

  set(install_hint
      "Install Node.js (>= 18) and npm, e.g. on Debian 12: sudo apt-get install nodejs npm "
      "(deploy/bootstrap.sh does this), then configure again. They run the independent MCAP "
      "reader (tests/record/mcap_reader_js) that checks every file `poise record` writes.")
  find_program(POISE_NODE_EXECUTABLE NAMES node nodejs DOC "Node.js for the MCAP reader tests")
  find_program(POISE_NPM_EXECUTABLE NAMES npm DOC "npm for the MCAP reader tests")
  if(NOT POISE_NODE_EXECUTABLE OR NOT POISE_NPM_EXECUTABLE)
    set(missing "")
    if(NOT POISE_NODE_EXECUTABLE)
      list(APPEND missing "node")
    endif()
    if(NOT POISE_NPM_EXECUTABLE)
      list(APPEND missing "npm")
    endif()
    list(JOIN missing " and " missing)
    message(FATAL_ERROR "The recorder tests need ${missing}, which were not found. " ${install_hint})
  endif()
  execute_process(COMMAND ${POISE_NODE_EXECUTABLE} --version
                  OUTPUT_VARIABLE node_version OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE node_rc)
  string(REGEX REPLACE "^v" "" node_version "${node_version}")
  if(NOT node_rc EQUAL 0 OR node_version VERSION_LESS 18)
    message(FATAL_ERROR "${POISE_NODE_EXECUTABLE} is Node.js '${node_version}'; the MCAP reader "
                        "tests need Node.js >= 18. " ${install_hint})
  endif()

  set(src ${POISE_MCAP_READER_JS_SOURCE_DIR})
  set(dir ${CMAKE_BINARY_DIR}/mcap_reader_js)
  set(stamp ${dir}/npm-ci.stamp)
  file(MAKE_DIRECTORY ${dir}) # the custom commands' working directory
  add_custom_command(
    OUTPUT ${stamp}
    COMMAND ${CMAKE_COMMAND} -E copy_if_different ${src}/package.json ${src}/package-lock.json
            ${dir}/
    COMMAND ${CMAKE_COMMAND} -E env npm_config_update_notifier=false
            ${POISE_NPM_EXECUTABLE} ci --no-audit --no-fund --ignore-scripts
    COMMAND ${CMAKE_COMMAND} -E touch ${stamp}
    DEPENDS ${src}/package.json ${src}/package-lock.json
    WORKING_DIRECTORY ${dir}
    COMMENT "npm ci: installing the MCAP reader's packages into ${dir}/node_modules"
    VERBATIM)
  set(outputs ${stamp})
  foreach(script mcap_check.mjs selftest.mjs)
    add_custom_command(
      OUTPUT ${dir}/${script}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${dir}
      COMMAND ${CMAKE_COMMAND} -E copy ${src}/${script} ${dir}/${script}
      DEPENDS ${src}/${script}
      COMMENT "Copying ${script} to ${dir}"
      VERBATIM)
    list(APPEND outputs ${dir}/${script})
  endforeach()
  add_custom_target(poise_mcap_reader_js ALL DEPENDS ${outputs})

  set(check ${POISE_NODE_EXECUTABLE} ${dir}/mcap_check.mjs)
  if(Python3_EXECUTABLE)
    set(python ${Python3_EXECUTABLE})
  else()
    find_program(POISE_PYTHON3_EXECUTABLE NAMES python3 REQUIRED)
    set(python ${POISE_PYTHON3_EXECUTABLE})
  endif()
  set(selftest ${POISE_NODE_EXECUTABLE} ${dir}/selftest.mjs
               --source-dir ${POISE_MCAP_READER_JS_ROOT} --python ${python})
  set(POISE_MCAP_CHECK "${check}" CACHE INTERNAL "Command prefix of the independent MCAP checker")
  set(POISE_MCAP_SELFTEST "${selftest}" CACHE INTERNAL "Command of the MCAP checker's self-test")
  set(POISE_MCAP_READER_JS_TARGET poise_mcap_reader_js CACHE INTERNAL "Target installing it")
  set(POISE_MCAP_CHECK "${check}" PARENT_SCOPE)
  set(POISE_MCAP_SELFTEST "${selftest}" PARENT_SCOPE)
  set(POISE_MCAP_READER_JS_TARGET poise_mcap_reader_js PARENT_SCOPE)

  if(ARG_SELFTEST_TEST)
    add_test(NAME ${ARG_SELFTEST_TEST} COMMAND ${selftest})
    set_tests_properties(${ARG_SELFTEST_TEST} PROPERTIES LABELS record TIMEOUT 600)
  endif()
endfunction()
