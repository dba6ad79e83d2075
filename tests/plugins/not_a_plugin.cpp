// A shared library without conesim's entry point (tests/app/sdk_test.sh).

extern "C" __attribute__((visibility("default"))) int some_other_library_function() {
  return 1;
}
