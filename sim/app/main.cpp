// The conesim command: the only translation unit that includes CLI11.

#include <CLI/CLI.hpp>
#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{"conesim: closed-loop Formula Student Driverless simulator"};
  app.set_version_flag("--version", std::string("conesim ") + CONESIM_VERSION);
  app.require_subcommand(1);
  auto* track = app.add_subcommand("track", "Read, check, generate and plot cone layouts");
  track->require_subcommand(1);
  CLI11_PARSE(app, argc, argv);
  return 0;
}
