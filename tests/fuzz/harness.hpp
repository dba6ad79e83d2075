#pragma once
// What the fuzz targets do with one input, shared by the libFuzzer targets (fuzz_target.cpp,
// built with CONESIM_FUZZ=ON) and the regression test that replays every input a fuzzer found
// (tests/data/fuzz/<target>/, fuzz_regression_test.cpp, in the default suite).
//
// Each target feeds the input to one reader as a user's file would reach it, and checks what a
// user would notice: the reader accepts it, or refuses it with a core::InputError that names the
// file; an accepted track survives a round trip through the formats conesim writes. Memory
// errors, undefined behaviour, hangs and memory blow-ups are the sanitizers' and libFuzzer's to
// catch.

#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"

namespace conesim::fuzz {

/// The names of the targets: fssim_yaml, pacsim_yaml, eufs_csv, epfl_csv (the track readers),
/// scenario (the scenario loader with --set overrides) and regress_json (a regress baseline
/// summary.json and a run's metrics.json as regress reads them). tests/fuzz/targets.txt gives
/// their seed folders.
const std::vector<std::string>& targets();

/// Runs target `name` on `input`. Returns "" when the input was read or refused as bad input
/// should be, otherwise what went wrong (an exception other than InputError, an error that does
/// not name the file, a round trip that loses cones). Throws std::invalid_argument for an
/// unknown target.
std::string run_target(const std::string& name, std::string_view input);

/// run_target for the track readers alone (fssim_yaml, pacsim_yaml, eufs_csv, epfl_csv): it
/// needs only the tracks library (harness_tracks.cpp).
std::string run_track_target(const std::string& name, std::string_view input);

/// An exception other than InputError as a report shows it: its type and message.
std::string describe(const std::exception& e);

/// "" when `e` names `name` (or the --set option) first, as every input error must; otherwise
/// what is wrong.
std::string check_names(const core::InputError& e, const std::string& name);

}  // namespace conesim::fuzz
