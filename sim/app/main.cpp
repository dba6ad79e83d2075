// The conesim command: the only translation unit that includes CLI11 (it costs seconds per file).

#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "core/error.hpp"
#include "sim/track_commands.hpp"
#include "tracks/io.hpp"

namespace {

using conesim::tracks::EventType;
namespace fs = std::filesystem;

// an --event option that accepts the four event names
CLI::Option* add_event_option(CLI::App* cmd, std::string& value, const std::string& help) {
  return cmd->add_option("--event", value, help)
      ->check(CLI::IsMember({"skidpad", "acceleration", "autocross", "trackdrive"}));
}

std::optional<EventType> parse_event(const std::string& name) {
  if (name.empty()) return std::nullopt;
  return conesim::tracks::event_from_string(name);
}

// `conesim track ...`
void add_track_commands(CLI::App& app, int& status) {
  auto* track = app.add_subcommand("track", "Read, check, generate, convert and plot cone layouts");
  track->require_subcommand(1);

  // validate
  {
    auto* cmd = track->add_subcommand(
        "validate", "Read track files and check them against the FSG rules. Exit 0 when every "
                    "file reads, 2 when one is malformed, 1 on rule violations with --strict");
    auto files = std::make_shared<std::vector<fs::path>>();
    auto event = std::make_shared<std::string>();
    auto strict = std::make_shared<bool>(false);
    cmd->add_option("FILE", *files, "Track files (fssim/PacSim YAML, EUFS/FSDS/EPFL CSV)")
        ->required();
    add_event_option(cmd, *event, "Check the rules of this event (default: recognised per file)");
    cmd->add_flag("--strict", *strict, "Exit 1 when a rule is broken");
    cmd->callback([=, &status] {
      status = conesim::sim::track_validate(*files, parse_event(*event), *strict, std::cout,
                                            std::cerr);
    });
  }

  // info
  {
    auto* cmd = track->add_subcommand("info", "Print a track's figures and rule violations as JSON");
    auto file = std::make_shared<fs::path>();
    auto event = std::make_shared<std::string>();
    cmd->add_option("FILE", *file, "Track file")->required();
    add_event_option(cmd, *event, "Check the rules of this event (default: recognised)");
    cmd->callback([=] {
      const auto t = conesim::tracks::read_track(*file);
      std::cout << conesim::sim::track_info(t, parse_event(*event)).dump(2) << "\n";
    });
  }

  // generate
  {
    auto* cmd = track->add_subcommand(
        "generate", "Make an FSG layout: skidpad, acceleration, or a random rule-compliant circuit");
    auto event = std::make_shared<std::string>("trackdrive");
    auto seed = std::make_shared<uint64_t>(0);
    auto out = std::make_shared<fs::path>();
    add_event_option(cmd, *event, "Event (default trackdrive)");
    cmd->add_option("--seed", *seed, "Seed of the random circuit (same seed, same track)");
    cmd->add_option("--out", *out, "Output file: .csv (EUFS CSV) or .yaml (PacSim YAML)")
        ->required();
    cmd->callback([=] {
      const auto t = conesim::sim::make_event_track(*parse_event(*event), *seed);
      conesim::sim::write_track_atomically(t, *out);
      std::cerr << "wrote " << out->string() << " (" << t.cones.size() << " cones)\n";
    });
  }

  // convert
  {
    auto* cmd = track->add_subcommand("convert", "Convert a track to EUFS CSV or PacSim YAML");
    auto in = std::make_shared<fs::path>();
    auto out = std::make_shared<fs::path>();
    cmd->add_option("IN", *in, "Input track file")->required();
    cmd->add_option("OUT", *out, "Output file: .csv (EUFS CSV) or .yaml (PacSim YAML)")->required();
    cmd->callback([=] {
      const auto t = conesim::tracks::read_track(*in);
      conesim::sim::write_track_atomically(t, *out);
    });
  }

  // plot
  {
    auto* cmd = track->add_subcommand("plot", "Draw a track to a PNG with gnuplot");
    auto file = std::make_shared<fs::path>();
    auto out = std::make_shared<fs::path>();
    auto event = std::make_shared<std::string>();
    cmd->add_option("FILE", *file, "Track file")->required();
    cmd->add_option("--out", *out, "Output PNG")->required();
    add_event_option(cmd, *event, "Mark violations of this event's rules (default: recognised)");
    cmd->callback([=] {
      const auto t = conesim::tracks::read_track(*file);
      conesim::sim::plot_track(t, parse_event(*event), *out);
    });
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conesim: closed-loop Formula Student Driverless simulator"};
  app.set_version_flag("--version", std::string("conesim ") + CONESIM_VERSION);
  app.require_subcommand(1);
  int status = 0;
  add_track_commands(app, status);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const conesim::core::InputError& e) {
    std::cerr << e.what() << "\n";
    return conesim::sim::kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "conesim: " << e.what() << "\n";
    return 3;
  }
  return status;
}
