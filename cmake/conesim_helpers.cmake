# conesim_library(NAME folder DEPS ...): one static library per folder, sources globbed.
function(conesim_library name)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  file(GLOB_RECURSE sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cpp)
  list(FILTER sources EXCLUDE REGEX "/app/")
  add_library(${name} STATIC ${sources})
  # position-independent: the reference driver plug-in (sdk/) and the Python module (python/)
  # link the static libraries into shared objects
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(${name} PUBLIC ${ARG_DEPS})
endfunction()

# conesim_tests(folder DEPS ...): one GoogleTest executable per *_test.cpp in tests/<folder>.
function(conesim_tests folder)
  cmake_parse_arguments(ARG "" "" "DEPS;LABELS" ${ARGN})
  file(GLOB test_sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${folder}/*_test.cpp)
  foreach(src IN LISTS test_sources)
    get_filename_component(stem ${src} NAME_WE)
    set(target test_${folder}_${stem})
    add_executable(${target} ${src})
    target_link_libraries(${target} PRIVATE ${ARG_DEPS} GTest::gtest_main GTest::gmock)
    target_compile_definitions(${target} PRIVATE
      CONESIM_TEST_DATA="${PROJECT_SOURCE_DIR}/tests/data"
      CONESIM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
    # files named *_slow_test.cpp run only with `./conesim test --all` (one label per test:
    # gtest_discover_tests does not pass a list through PROPERTIES)
    set(labels ${folder})
    if(stem MATCHES "_slow_test$")
      set(labels slow)
    endif()
    math(EXPR timeout "1800 * ${CONESIM_TEST_TIMEOUT_SCALE}")
    gtest_discover_tests(${target} TEST_PREFIX "${folder}." DISCOVERY_TIMEOUT 60
      PROPERTIES LABELS "${labels}" TIMEOUT ${timeout})
  endforeach()
endfunction()

# conesim_scale_timeouts(): each test added in the calling folder gets its TIMEOUT multiplied by
# CONESIM_TEST_TIMEOUT_SCALE (the sanitizer build's slowdown; 1 otherwise)
function(conesim_scale_timeouts)
  get_directory_property(tests TESTS)
  foreach(test IN LISTS tests)
    get_test_property(${test} TIMEOUT timeout)
    if(timeout)
      math(EXPR timeout "${timeout} * ${CONESIM_TEST_TIMEOUT_SCALE}")
      set_tests_properties(${test} PROPERTIES TIMEOUT ${timeout})
    endif()
  endforeach()
endfunction()
