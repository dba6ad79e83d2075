// One libFuzzer target (CONESIM_FUZZ_TARGET names it): the input goes to run_target, and a
// problem it reports aborts, so that libFuzzer keeps the input as a finding.

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "tests/fuzz/harness.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
#ifdef CONESIM_FUZZ_TRACKS_ONLY
  const std::string problem = conesim::fuzz::run_track_target(CONESIM_FUZZ_TARGET, input);
#else
  const std::string problem = conesim::fuzz::run_target(CONESIM_FUZZ_TARGET, input);
#endif
  if (!problem.empty()) {
    std::fprintf(stderr, "conesim fuzz %s: %s\n", CONESIM_FUZZ_TARGET, problem.c_str());
    std::abort();
  }
  return 0;
}
