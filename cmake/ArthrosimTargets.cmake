# arthrosim_library(NAME SOURCES a.cpp ... DEPS target ...)
# One static library per subsystem; public headers live in include/arthrosim/<sub>/.
function(arthrosim_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${CMAKE_SOURCE_DIR}/include ${CMAKE_BINARY_DIR}/generated)
  target_link_libraries(${name} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
endfunction()

# arthrosim_test(NAME SOURCES a_test.cpp ... DEPS target ... [TIMEOUT s] [LABELS ...] [FIXTURES F])
# One GoogleTest executable per subsystem test file group, registered with CTest.
# Tests run with the source tree as working directory so they can read scenarios/ and tests/testdata/.
# FIXTURES: a CTest fixture every test of NAME requires (the scene runs it reads, tests/cli).
function(arthrosim_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT;FIXTURES" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE ARTHROSIM_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                                             ARTHROSIM_BINARY_DIR="${CMAKE_BINARY_DIR}")
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  set(fixtures "")
  if(ARG_FIXTURES)
    set(fixtures FIXTURES_REQUIRED ${ARG_FIXTURES})
  endif()
  gtest_discover_tests(${name} WORKING_DIRECTORY ${CMAKE_SOURCE_DIR}
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT} ${fixtures} LABELS "${ARG_LABELS}"
                       DISCOVERY_TIMEOUT 60)
endfunction()
