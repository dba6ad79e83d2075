// The conesim command: the only translation unit that includes CLI11 (it costs seconds per file).

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "sim/autonomy.hpp"
#include "sim/bench.hpp"
#include "sim/compare.hpp"
#include "sim/dataset.hpp"
#include "sim/interrupt.hpp"
#include "sim/json_text.hpp"
#include "sim/regress.hpp"
#include "sim/replay.hpp"
#include "sim/replay_video.hpp"
#include "sim/run.hpp"
#include "sim/scenario.hpp"
#include "sim/slurm.hpp"
#include "sim/track_commands.hpp"
#include "tracks/io.hpp"
#include "vehicle_models/steering.hpp"

namespace {

using conesim::tracks::EventType;
namespace fs = std::filesystem;

// an --event option that accepts the four event names
CLI::Option* add_event_option(CLI::App* cmd, std::string& value, const std::string& help) {
  return cmd->add_option("--event", value, help)
      ->check(CLI::IsMember({"skidpad", "acceleration", "autocross", "trackdrive"}));
}

// an output file must go into a folder that exists: bad input otherwise, not a failed tool
void check_output_folder(const fs::path& file) {
  const fs::path folder = file.parent_path();
  std::error_code ec;
  if (!folder.empty() && !fs::is_directory(folder, ec))
    throw conesim::core::InputError(file.string(), 0, "cannot write: no folder " + folder.string());
}

std::optional<EventType> parse_event(const std::string& name) {
  if (name.empty()) return std::nullopt;
  return conesim::tracks::event_from_string(name);
}

// the generator profiles' names, for --profile
std::vector<std::string> profile_names() {
  std::vector<std::string> names;
  for (auto p : conesim::tracks::all_profiles()) names.emplace_back(conesim::tracks::to_string(p));
  names.emplace_back("mixed");
  return names;
}

conesim::tracks::TravelDirection parse_direction(const std::string& name) {
  using conesim::tracks::TravelDirection;
  if (name == "cw" || name == "clockwise") return TravelDirection::kClockwise;
  if (name == "ccw" || name == "counter-clockwise") return TravelDirection::kCounterClockwise;
  return TravelDirection::kFromSeed;
}

// a --direction option
CLI::Option* add_direction_option(CLI::App* cmd, std::string& value) {
  return cmd
      ->add_option("--direction", value,
                   "Direction of travel: cw, ccw or seed (drawn from the seed, the default)")
      ->check(CLI::IsMember({"cw", "ccw", "clockwise", "counter-clockwise", "seed"}));
}

// the car of --vehicle: a YAML file or 'default'
conesim::vehicle_models::VehicleParams vehicle_of(const std::string& file) {
  return file.empty() || file == "default" ? conesim::vehicle_models::VehicleParams{}
                                           : conesim::sim::load_vehicle(file);
}

// `conesim track ...`
void add_track_commands(CLI::App& app, int& status) {
  auto* track = app.add_subcommand("track", "Read, check, generate, convert and plot cone layouts");
  track->require_subcommand(1);

  // validate
  {
    auto* cmd = track->add_subcommand(
        "validate",
        "Read track files and check them against the FSG rules. Exit 0 when every "
        "file reads, 2 when one is malformed, 1 on rule violations with --strict");
    auto files = std::make_shared<std::vector<fs::path>>();
    auto event = std::make_shared<std::string>();
    auto strict = std::make_shared<bool>(false);
    cmd->add_option("FILE", *files, "Track files (fssim/PacSim YAML, EUFS/FSDS/EPFL CSV)")
        ->required();
    add_event_option(cmd, *event, "Check the rules of this event (default: recognised per file)");
    cmd->add_flag("--strict", *strict, "Exit 1 when a rule is broken");
    cmd->callback([=, &status] {
      status =
          conesim::sim::track_validate(*files, parse_event(*event), *strict, std::cout, std::cerr);
    });
  }

  // info
  {
    auto* cmd =
        track->add_subcommand("info", "Print a track's figures and rule violations as JSON");
    auto file = std::make_shared<fs::path>();
    auto event = std::make_shared<std::string>();
    cmd->add_option("FILE", *file, "Track file")->required();
    add_event_option(cmd, *event, "Check the rules of this event (default: recognised)");
    cmd->callback([=] {
      const auto t = conesim::tracks::read_track(*file);
      std::cout << conesim::sim::json_text(conesim::sim::track_info(t, parse_event(*event)), 2) << "\n";
    });
  }

  // generate
  {
    auto* cmd = track->add_subcommand(
        "generate",
        "Make an FSG layout: skidpad, acceleration, or a random rule-compliant circuit");
    auto event = std::make_shared<std::string>("trackdrive");
    auto seed = std::make_shared<uint64_t>(0);
    auto out = std::make_shared<fs::path>();
    auto profile = std::make_shared<std::string>("standard");
    auto direction = std::make_shared<std::string>("seed");
    add_event_option(cmd, *event, "Event (default trackdrive)");
    cmd->add_option("--seed", *seed, "Seed of the random circuit (same seed, same track)");
    cmd->add_option("--out", *out, "Output file: .csv (EUFS CSV) or .yaml (PacSim YAML)")
        ->required();
    cmd->add_option("--profile", *profile,
                    "Circuit profile: standard, hairpins, slalom, chicanes, narrow, "
                    "straight-into-hairpin, hard (or mixed)")
        ->check(CLI::IsMember(profile_names()));
    add_direction_option(cmd, *direction);
    auto hairpin =
        std::make_shared<double>(conesim::tracks::GeneratorParams{}.hairpin_outer_diameter_m);
    cmd->add_option("--hairpin-diameter", *hairpin,
                    "Outside diameter of the profiles' minimum hairpins, m (default 9.2: the FSG "
                    "9 m and a margin)")
        ->check(CLI::Range(9.2, 20.0));
    cmd->callback([=] {
      conesim::tracks::GeneratorParams circuit;
      circuit.profile = *conesim::tracks::profile_from_string(*profile);
      circuit.direction = parse_direction(*direction);
      circuit.hairpin_outer_diameter_m = *hairpin;
      const auto t = conesim::sim::make_event_track(*parse_event(*event), *seed, circuit);
      conesim::sim::write_track_atomically(t, *out);
      std::cerr << "wrote " << out->string() << " (" << t.cones.size() << " cones)\n";
    });
  }

  // corpus
  {
    auto* cmd = track->add_subcommand(
        "corpus",
        "Write N generated circuits from a seed and an index.json. Exit 1 when one "
        "could not be made or breaks a rule");
    auto options = std::make_shared<conesim::sim::CorpusOptions>();
    auto profiles = std::make_shared<std::vector<std::string>>();
    auto events = std::make_shared<std::vector<std::string>>();
    auto direction = std::make_shared<std::string>("seed");
    auto vehicle = std::make_shared<std::string>("default");
    cmd->add_option("--count", options->count, "Layouts to write")->check(CLI::Range(1, 100000));
    cmd->add_option("--seed", options->seed, "Seed of the first layout (layout i: seed + i)");
    cmd->add_option("--profile", *profiles,
                    "Profiles taken in turn, comma-separated (default hard)")
        ->delimiter(',')
        ->check(CLI::IsMember(profile_names()));
    cmd->add_option("--event", *events,
                    "Events taken in turn, comma-separated: autocross, trackdrive (default "
                    "trackdrive)")
        ->delimiter(',')
        ->check(CLI::IsMember({"autocross", "trackdrive"}));
    add_direction_option(cmd, *direction);
    cmd->add_option("--format", options->format, "File format: csv or yaml")
        ->check(CLI::IsMember({"csv", "yaml"}));
    cmd->add_option("--vehicle", *vehicle, "Vehicle YAML for the index's lap-time bounds");
    cmd->add_option("--hairpin-diameter", options->hairpin_outer_diameter_m,
                    "Outside diameter of the minimum hairpins, m (default 9.2)")
        ->check(CLI::Range(9.2, 20.0));
    cmd->add_option("--out", options->out_dir, "Output folder")->required();
    cmd->callback([=, &status] {
      conesim::sim::CorpusOptions o = *options;
      if (!profiles->empty()) {
        o.profiles.clear();
        for (const auto& p : *profiles)
          o.profiles.push_back(*conesim::tracks::profile_from_string(p));
      }
      if (!events->empty()) {
        o.events.clear();
        for (const auto& e : *events) o.events.push_back(*parse_event(e));
      }
      o.direction = parse_direction(*direction);
      o.vehicle = vehicle_of(*vehicle);
      status = conesim::sim::track_corpus(o, std::cout, std::cerr);
    });
  }

  // laptime
  {
    auto* cmd = track->add_subcommand(
        "laptime", "Print the quasi-steady-state lap-time bound of a layout as JSON");
    auto file = std::make_shared<fs::path>();
    auto event = std::make_shared<std::string>();
    auto vehicle = std::make_shared<std::string>("default");
    auto grip = std::make_shared<double>(1.0);
    auto csv = std::make_shared<fs::path>();
    cmd->add_option("FILE", *file, "Track file")->required();
    add_event_option(cmd, *event, "Time the layout as this event (default: recognised)");
    cmd->add_option("--vehicle", *vehicle, "Vehicle YAML file, or 'default'");
    cmd->add_option("--grip-fraction", *grip,
                    "Share of the measured grip (default 1: the full measured grip)")
        ->check(CLI::Range(0.05, 2.0));
    cmd->add_option("--profile-csv", *csv, "Also write the speed profile: s_m,speed_mps,x_m,y_m");
    cmd->callback([=, &status] {
      const auto t = conesim::tracks::read_track(*file);
      const auto v = vehicle_of(*vehicle);
      conesim::laptime::LapTimeOptions options;
      options.grip_fraction = *grip;
      options.event = parse_event(*event);
      const auto bound = conesim::laptime::lap_time_bound(t, v, options);
      std::cout << conesim::sim::json_text(conesim::sim::lap_time_json(t, bound, v, *grip), 2) << "\n";
      if (!csv->empty() && bound.usable) conesim::sim::write_speed_profile_csv(bound, *csv);
      if (!bound.usable) status = 1;
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
      check_output_folder(*out);
      conesim::sim::plot_track(t, parse_event(*event), *out);
    });
  }
}

// `conesim run SCENARIO ...`
// a plug-in's call that never returned (`conesim run` owns its process, so its plug-ins run on
// the run's own thread under a watchdog): the folder says why it is incomplete, stderr gives the
// DNF, and the process ends with a DNF's exit status. Set before the run, read on the
// watchdog's thread.
std::string hang_run_folder;

[[noreturn]] void end_run_on_plugin_hang(const std::string& reason) {
  const fs::path incomplete = fs::path(hang_run_folder) / conesim::sim::kIncompleteFile;
  if (FILE* f = std::fopen(incomplete.c_str(), "w")) {
    std::fprintf(f,
                 "DNF: %s. The run was stopped there (a call that never returns cannot be "
                 "abandoned inside the process) and wrote no metrics.json\n",
                 reason.c_str());
    std::fclose(f);
  }
  std::fprintf(stderr, "DNF (%s): %s has no metrics.json (see %s)\n", reason.c_str(),
               hang_run_folder.c_str(), conesim::sim::kIncompleteFile);
  std::fflush(stderr);
  std::_Exit(1);
}

void add_run_command(CLI::App& app, int& status) {
  auto* cmd = app.add_subcommand("run", "Run one scenario in closed loop and score it");
  auto scenario = std::make_shared<std::string>();
  auto track = std::make_shared<fs::path>();
  auto seed = std::make_shared<uint64_t>();
  auto out = std::make_shared<fs::path>();
  auto sets = std::make_shared<std::vector<std::string>>();
  auto no_plot = std::make_shared<bool>(false);
  cmd->add_option("SCENARIO", *scenario,
                  "Scenario file, or the name of a shipped one (skidpad, acceleration, "
                  "autocross, trackdrive)")
      ->required();
  cmd->add_option("--track", *track, "Run on this track file instead of the scenario's");
  auto* seed_opt = cmd->add_option("--seed", *seed, "Seed (also the generated circuit's)");
  cmd->add_option("--out", *out, "Run directory (default runs/<name>-<UTC stamp>)");
  cmd->add_option("--set", *sets, "Override a scenario value: key.path=value (repeatable)");
  cmd->add_flag("--no-plot", *no_plot, "Skip the PNG (no gnuplot run)");
  auto dump = std::make_shared<std::vector<std::string>>();
  auto dump_every = std::make_shared<int>(conesim::sim::DumpOptions{}.every);
  cmd->add_option("--dump", *dump,
                  "Write sensor data under images/: lidar, camera, detections (comma-separated; "
                  "dumping a sensor switches it on)")
      ->delimiter(',')
      ->check(CLI::IsMember({"lidar", "camera", "detections"}));
  cmd->add_option("--dump-every", *dump_every, "Dump every Nth frame of each sensor (default 10: one a second of a "
                  "10 Hz sensor; 1 dumps every frame, at a cost: docs/review.md)")
      ->check(CLI::Range(1, 1000000));
  auto replay = std::make_shared<bool>(false);
  cmd->add_flag("--replay", *replay,
                "Record the run for its 3D replay and write replay.html (see `conesim view`)");
  cmd->callback([=, &status] {
    namespace sim = conesim::sim;
    sim::install_interrupt_handlers();
    // every input is checked before the run folder is touched
    const fs::path file = sim::find_scenario(*scenario);
    sim::Scenario s = sim::load_scenario(
        file, *sets, seed_opt->count() > 0 ? std::optional<uint64_t>(*seed) : std::nullopt);
    for (const std::string& w : s.warnings) std::cerr << "warning: " << w << "\n";
    if (!track->empty()) {
      s.track.file = *track;
      s.track.generate_seed.reset();
    }
    const conesim::tracks::Track t = sim::scenario_track(s);
    for (const std::string& w : t.warnings) std::cerr << "warning: " << w << "\n";
    if (const std::string why = sim::run_bounds_problem(t); !why.empty())
      throw conesim::core::InputError(s.track.file ? s.track.file->string() : t.name, 0, why);
    // a circuit this car cannot drive is refused before any run folder is made
    if (s.driver.check_drivable) {
      if (const std::string why = sim::drivability_problem(s, t); !why.empty())
        throw conesim::core::InputError(
            s.track.file ? s.track.file->string() : t.name, 0,
            "not drivable by this car: " + why + " (driver.check_drivable=false runs it anyway)");
    }

    // each plug-in is made once with its configuration: one that refuses it stops here
    if (s.driver_plugin || s.slam_plugin || s.perception_plugin)
      sim::check_plugins(s,
                         sim::make_run_info(s, sim::driver_vehicle(s.vehicle), t.start, {})->info);

    sim::RunOptions options;
    options.plot = !*no_plot;
    options.dump.sensors = {dump->begin(), dump->end()};
    options.dump.every = *dump_every;
    options.replay = *replay;
    std::error_code ec;
    const bool existed = !out->empty() && fs::exists(*out, ec);
    try {
      options.out_dir = out->empty() ? sim::make_run_dir("runs", s.name) : *out;
      fs::create_directories(options.out_dir);
    } catch (const fs::filesystem_error& e) {
      throw conesim::core::InputError(out->empty() ? "runs" : "--out " + out->string(), 0,
                                      "cannot create the run folder: " + e.code().message());
    }
    // a folder the results cannot be written to (read-only, full) is refused now; one made
    // for this run is removed again
    try {
      sim::check_output_writable(options.out_dir);
    } catch (const conesim::core::InputError&) {
      if (!existed) fs::remove(options.out_dir, ec);
      throw;
    }
    // plug-ins' calls run on the run's threads, watched; one that never returns ends the process
    hang_run_folder = options.out_dir.string();
    sim::set_plugin_hang_handler(end_run_on_plugin_hang);
    // the live progress line only on a terminal
    const bool tty = isatty(STDERR_FILENO);
    if (tty) {
      options.on_progress = [&s](const sim::Progress& p) {
        std::fprintf(stderr, "\r%s  lap %d/%d  t %.1f s  %.0fx real time  %s\033[K",
                     std::string(conesim::core::to_string(s.event)).c_str(), p.laps, p.laps_target,
                     p.sim_time_s, p.real_time_factor, p.driver_state.c_str());
      };
    }
    const sim::RunResult r = sim::run_scenario(s, t, options);
    if (tty) std::fprintf(stderr, "\r\033[K");
    if (r.interrupted_by != 0) {
      std::fprintf(stderr,
                   "interrupted by %s at sim time %.1f s: %s has no metrics.json (see %s)\n",
                   sim::signal_name(r.interrupted_by), r.sim_time_s,
                   options.out_dir.string().c_str(), sim::kIncompleteFile);
      status = sim::interrupted_exit_status(r.interrupted_by);
      return;
    }

    // one summary on stdout
    const auto& ref = r.referee;
    std::printf("%s on %s (seed %llu): %s", std::string(conesim::core::to_string(s.event)).c_str(),
                t.name.c_str(), static_cast<unsigned long long>(s.seed),
                ref.completed ? "completed" : ("DNF (" + ref.dnf_reason + ")").c_str());
    std::printf(", %d laps, %.3f s, %zu cones hit, %d off-course, %.0fx real time\n", ref.laps,
                ref.final_time_s, ref.cones_hit.size(), ref.off_course,
                r.sim_time_s / std::max(r.wall_time_s, 1e-9));
    for (const auto& f : r.failures) std::printf("fail: %s\n", f.c_str());
    for (const auto& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    std::printf("%s\n", options.out_dir.string().c_str());
    status = r.passed ? 0 : 1;
  });
}

// `conesim view RUN_DIR`
void add_view_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "view",
      "Write RUN_DIR/replay.html: a 3D replay of a run that opens from disk in a browser (the "
      "LiDAR and the growing SLAM maps when the run was made with --replay)");
  auto dir = std::make_shared<fs::path>();
  cmd->add_option("RUN_DIR", *dir, "A run folder (conesim run --out)")->required();
  auto mp4 = std::make_shared<bool>(false);
  auto video = std::make_shared<conesim::sim::VideoSettings>();
  cmd->add_flag("--mp4", *mp4,
                "Write RUN_DIR/replay.mp4 instead: the run top-down, encoded by ffmpeg");
  auto mp4_view = std::make_shared<std::string>("top");
  cmd->add_option("--mp4-view", *mp4_view,
                  "What the video shows (implies --mp4): top (replay.mp4, the default), chase "
                  "(replay-chase.mp4: from behind and above the car, following it) or camera "
                  "(replay-camera.mp4: the recorded left camera frames with the detected and "
                  "true boxes; needs a run with the stereo camera made with --replay)")
      ->check(CLI::IsMember({"top", "chase", "camera"}));
  cmd->add_option("--fps", video->fps, "Frames per second of the video (--mp4)")
      ->check(CLI::PositiveNumber);
  cmd->callback([=] {
    using conesim::sim::VideoView;
    video->view = *mp4_view == "chase"    ? VideoView::kChase
                  : *mp4_view == "camera" ? VideoView::kCamera
                                          : VideoView::kTop;
    const bool want_video = *mp4 || cmd->count("--mp4-view") > 0;
    const fs::path page =
        want_video ? conesim::sim::write_replay_video(*dir, *video)
                   : conesim::sim::write_replay_page(*dir, conesim::sim::default_three_js_dir());
    std::error_code ec;
    std::printf("%s (%.1f MB)\n", page.string().c_str(),
                static_cast<double>(fs::file_size(page, ec)) / 1e6);
  });
}

// --shard, --only-missing, --slurm and the sbatch options of regress and compare
struct ShardingFlags {
  std::string shard;
  fs::path only_missing;
  conesim::sim::SlurmOptions slurm;
  bool use_slurm = false;
};

void add_sharding_options(CLI::App* cmd, ShardingFlags& f) {
  cmd->add_option("--shard", f.shard,
                  "I/N: run only shard I of N (slices balanced by expected cost, the same on "
                  "every machine); `conesim merge` joins the shards' --out folders");
  cmd->add_option("--only-missing", f.only_missing,
                  "MERGE_DIR: run only the runs the merge in MERGE_DIR lists as missing (with "
                  "the shards' arguments), then merge again into MERGE_DIR");
  cmd->add_flag("--slurm", f.use_slurm,
                "Submit to Slurm instead of running here: a job array of --shards tasks into "
                "OUT/shard-K and a merge job into OUT, with sbatch; prints the job ids");
  cmd->add_option("--shards", f.slurm.shards, "With --slurm: the number of shards (default 4)")
      ->check(CLI::Range(1, 10000));
  cmd->add_option("--partition", f.slurm.partition, "With --slurm: sbatch --partition");
  cmd->add_option("--time", f.slurm.time,
                  "With --slurm: sbatch --time of each task (e.g. 1:00:00)");
  cmd->add_option("--cpus-per-task", f.slurm.cpus_per_task,
                  "With --slurm: sbatch --cpus-per-task; each task runs that many runs at once")
      ->check(CLI::Range(1, 1024));
}

// the sbatch options only with --slurm; --slurm and --only-missing not with what makes a call
// one part of the list (--shard, `resume`: --resume or --reuse), --only-missing not with --out
void check_sharding_options(CLI::App* cmd, const ShardingFlags& f, bool sharded, bool resumed,
                            const std::string& resume, bool out_given) {
  using conesim::core::InputError;
  for (const char* opt : {"--shards", "--partition", "--time", "--cpus-per-task"})
    if (cmd->count(opt) && !f.use_slurm) throw InputError(opt, 0, "only with --slurm");
  if (f.use_slurm && (sharded || !f.only_missing.empty() || resumed))
    throw InputError("--slurm", 0,
                     "not with --shard, --only-missing or " + resume +
                         ": --slurm runs every shard itself");
  if (!f.only_missing.empty() && (sharded || resumed || out_given))
    throw InputError("--only-missing", 0,
                     "not with --shard, " + resume + " or --out: the runs go into "
                     "MERGE_DIR/rerun-K");
}

// `conesim regress ...`
void add_regress_command(CLI::App& app, int& status, int argc, char** argv) {
  auto* cmd = app.add_subcommand(
      "regress",
      "Run scenarios x tracks x seeds in parallel processes; write summary.json, junit.xml and "
      "summary.html. Exit 0 when every run passed (and nothing regressed against --baseline), "
      "1 when not, 2 for bad input");
  auto o = std::make_shared<conesim::sim::RegressOptions>();
  auto seeds = std::make_shared<std::string>();
  auto generated = std::make_shared<std::string>();
  auto baseline = std::make_shared<fs::path>();
  auto no_plot = std::make_shared<bool>(false);
  o->jobs = std::max(1, static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN)));
  cmd->add_option("SCENARIO", o->scenarios,
                  "Scenarios to run (default: the shipped events and GraphSLAM scenarios; on "
                  "given tracks, each track's own event)");
  cmd->add_option("--track", o->track_files, "Run on this track file (repeatable)");
  cmd->add_option("--tracks", o->track_sets,
                  "A folder of track files, a list file (one path a line), or `corpus` (the "
                  "public layouts shipped in tests/data/tracks); repeatable");
  cmd->add_option("--generated", *generated,
                  "N[:PROFILE]: also N generated circuits, seeds 1..N (`conesim track generate "
                  "--event trackdrive`, with --profile PROFILE when given)");
  cmd->add_option("--seeds", *seeds, "Seeds of every run: 1,2,3 or 1-5 (default: per scenario)");
  cmd->add_option("--set", o->sets, "Override a scenario value in every run: key.path=value");
  cmd->add_option("--jobs,-j", o->jobs, "Runs at once (default: the number of cores)")
      ->check(CLI::Range(1, 256));
  cmd->add_option("--out", o->out_dir, "Folder of the runs (default runs/regress-<UTC stamp>)");
  cmd->add_option("--baseline", *baseline,
                  "A stored summary.json: exit 1 on a regression beyond the noise");
  cmd->add_flag("--no-plot", *no_plot, "Runs draw no pictures (faster; report.html has none)");
  auto list = std::make_shared<bool>(false);
  cmd->add_flag("--list", *list,
                "Print the runs (id, folder, expected cost) and stop: nothing runs; without "
                "--shard also how the cost spreads over 1 to 32 shards");
  cmd->add_flag("--resume", o->resume,
                "With --out of an earlier, interrupted call with the same runs: the runs that "
                "wrote their metrics.json are read, the others run");
  auto sharding = std::make_shared<ShardingFlags>();
  add_sharding_options(cmd, *sharding);
  cmd->callback([=, &status] {
    namespace sim = conesim::sim;
    sim::install_interrupt_handlers();
    if (!sharding->shard.empty()) o->shard = sim::parse_shard(sharding->shard);
    check_sharding_options(cmd, *sharding, o->shard.active(), o->resume, "--resume",
                           !o->out_dir.empty());
    {
      int k = 1;
      while (k < argc && std::string(argv[k]) != "regress") ++k;
      for (++k; k < argc; ++k) o->args.push_back(argv[k]);
    }
    if (o->resume && o->out_dir.empty())
      throw conesim::core::InputError("--resume", 0,
                                      "needs --out: the folder of the interrupted regress");
    // the options, checked before any run starts
    if (!seeds->empty()) o->seeds = sim::parse_seeds(*seeds);
    if (!generated->empty()) {
      const size_t colon = generated->find(':');
      const std::string count = generated->substr(0, colon);
      if (count.empty() || count.find_first_not_of("0123456789") != std::string::npos ||
          count.size() > 5)
        throw conesim::core::InputError("--generated", 0,
                                        "expected N or N:PROFILE, got '" + *generated + "'");
      o->generated = std::stoi(count);
      if (colon != std::string::npos) o->generated_profile = generated->substr(colon + 1);
    }
    if (!baseline->empty()) o->baseline = *baseline;
    o->plot = !*no_plot;
    for (int i = 0; i < argc; ++i) o->command_line.append(i ? " " : "").append(argv[i]);
    std::error_code ec;
    fs::path self = fs::read_symlink("/proc/self/exe", ec);
    if (ec) self = fs::absolute(argv[0]);
    if (!sharding->only_missing.empty()) {
      status = sim::rerun_missing(self, *o, sharding->only_missing, std::cout, std::cerr);
      return;
    }
    if (o->out_dir.empty()) o->out_dir = sim::make_run_dir("runs", "regress");
    if (*list) {
      const sim::RegressionPlan plan = sim::plan_regression(self, *o);
      const std::vector<sim::RegressionRun> runs = sim::selected_runs(plan, *o);
      double cost = 0.0;
      for (const auto& r : runs) {
        std::cout << r.id() << "  " << r.dir.string() << "  cost " << r.cost << "\n";
        cost += r.cost;
      }
      for (const auto& t : plan.skipped)
        std::cout << "skipped " << t.track << ": " << t.reason << "\n";
      std::cout << runs.size() << " runs";
      if (o->shard.active()) std::cout << " of " << plan.runs.size() << " (shard " << o->shard.text() << ")";
      std::cout << ", expected cost " << cost << "\n";
      if (!o->shard.active() && o->only_ids.empty()) {
        std::vector<double> costs;
        for (const auto& r : plan.runs) costs.push_back(r.cost);
        sim::print_shard_scaling(costs, std::cout);
      }
      return;
    }
    // after --list, which only shows the runs: --slurm --list submits nothing
    if (sharding->use_slurm) {
      if (cmd->count("--jobs")) sharding->slurm.jobs = o->jobs;
      status = sim::submit_regression_to_slurm(self, *o, sharding->slurm, std::cout, std::cerr);
      return;
    }
    status = sim::run_regression(self, *o, std::cout, std::cerr);
    std::cout << o->out_dir.string() << "\n";
  });
}

// `conesim merge DIR... --out DIR`
void add_merge_command(CLI::App& app, int& status, int argc, char** argv) {
  auto* cmd = app.add_subcommand(
      "merge",
      "Join the --out folders of `conesim regress --shard I/N` (and of --only-missing reruns) "
      "into the summary.json, junit.xml and summary.html one unsharded regress writes, or those "
      "of `conesim compare --shard I/N` into its compare.json, compare.md and compare.html. Runs "
      "with no result are listed as missing, with the command that runs only them. "
      "Exit 0 when every run is there and passed, 1 otherwise, 2 for bad input");
  auto m = std::make_shared<conesim::sim::MergeOptions>();
  auto baseline = std::make_shared<fs::path>();
  auto expect = std::make_shared<fs::path>();
  cmd->add_option("DIR", m->dirs, "The shards' --out folders")->required();
  cmd->add_option("--out", m->out_dir, "Folder of the merged summaries")->required();
  cmd->add_option("--baseline", *baseline,
                  "A stored summary.json (default: the shards' own --baseline, if any; regress "
                  "shards only)");
  cmd->add_option("--expect", *expect,
                  "A summary.json (compare.json for compare shards) the merged one must equal "
                  "apart from timing (exit 1 and the differences when not): e.g. the unsharded "
                  "run's");
  cmd->callback([=, &status] {
    if (!baseline->empty()) m->baseline = *baseline;
    if (!expect->empty()) m->expect = *expect;
    for (int i = 0; i < argc; ++i) m->command_line.append(i ? " " : "").append(argv[i]);
    // compare shards or regress shards: their plan.json says which
    status = conesim::sim::holds_compare_plan(m->dirs)
                 ? conesim::sim::merge_compare(*m, std::cout, std::cerr)
                 : conesim::sim::merge_regression(*m, std::cout, std::cerr);
    std::cout << m->out_dir.string() << "\n";
  });
}

// `conesim slurm status JOB...`
void add_slurm_commands(CLI::App& app, int& status) {
  auto* slurm = app.add_subcommand("slurm", "Follow a regress or compare submitted with --slurm");
  slurm->require_subcommand(1);
  auto* cmd = slurm->add_subcommand(
      "status",
      "Per job, its tasks by state (sacct; squeue without accounting). Exit 0 when all "
      "completed, 1 when one failed or was cancelled, 3 while some run, 2 for an unknown job");
  auto jobs = std::make_shared<std::vector<std::string>>();
  auto wait = std::make_shared<bool>(false);
  cmd->add_option("JOB", *jobs, "Job ids, or the --out folder of `conesim regress --slurm` (or compare)")
      ->required();
  cmd->add_flag("--wait", *wait, "Wait until no task is pending or running");
  cmd->callback([=, &status] {
    status = conesim::sim::slurm_status(*jobs, *wait, 2.0, std::cout, std::cerr);
  });
}

// `conesim compare STUDY ...`
void add_compare_command(CLI::App& app, int& status, int argc, char** argv) {
  auto* cmd = app.add_subcommand(
      "compare",
      "Run a study of the SLAM theses (fst, raceup, monash, all): every method on the same "
      "observations, tracks x seeds x conditions in parallel processes; write compare.md, "
      "compare.json and compare.html beside the runs. Exit 0 when every run gave its figures, 1 "
      "when one did not (named), 2 for bad input");
  auto o = std::make_shared<conesim::sim::CompareOptions>();
  auto seeds = std::make_shared<std::string>();
  auto no_plot = std::make_shared<bool>(false);
  auto list = std::make_shared<bool>(false);
  o->jobs = std::min(2, std::max(1, static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN))));
  cmd->add_option("STUDY", o->study, "fst, raceup, monash or all")->required();
  cmd->add_option("--jobs,-j", o->jobs, "Runs at once (default: 2, or 1 on one core)")
      ->check(CLI::Range(1, 256));
  cmd->add_option("--out", o->out_dir,
                  "Folder of the runs (default runs/compare-STUDY-<UTC stamp>)");
  cmd->add_option("--track", o->track_files,
                  "Run on this track instead of the study's (repeatable; a quick look)");
  cmd->add_option("--seeds", *seeds, "Seeds instead of the study's: 1,2,3 or 1-5");
  cmd->add_option("--set", o->sets,
                  "Override a scenario value in every run, after the study's own: key.path=value");
  cmd->add_flag("--no-plot", *no_plot, "Draw no figures");
  cmd->add_flag("--reuse", o->reuse,
                "With --out of an earlier call: runs that wrote their metrics.json are read, not "
                "run again (the outputs are written anew)");
  cmd->add_flag("--list", *list,
                "Print the runs (id, folder, expected cost) and stop: nothing runs; without "
                "--shard also how the cost spreads over 1 to 32 shards");
  auto sharding = std::make_shared<ShardingFlags>();
  add_sharding_options(cmd, *sharding);
  cmd->callback([=, &status] {
    namespace sim = conesim::sim;
    if (!seeds->empty()) o->seeds = sim::parse_seeds(*seeds);
    if (!sharding->shard.empty()) o->shard = sim::parse_shard(sharding->shard);
    check_sharding_options(cmd, *sharding, o->shard.active(), o->reuse, "--reuse",
                           !o->out_dir.empty());
    o->plot = !*no_plot;
    for (int i = 0; i < argc; ++i) o->command_line.append(i ? " " : "").append(argv[i]);
    {
      int k = 1;
      while (k < argc && std::string(argv[k]) != "compare") ++k;
      for (++k; k < argc; ++k) o->args.push_back(argv[k]);
    }
    std::error_code ec;
    fs::path self = fs::read_symlink("/proc/self/exe", ec);
    if (ec) self = fs::absolute(argv[0]);
    if (*list) {
      const sim::StudyPlan plan = sim::plan_study(*o);
      double cost = 0.0;
      const std::vector<size_t> picked = sim::selected_study_runs(plan, *o);
      for (size_t i : picked) {
        const auto& r = plan.runs[i];
        std::cout << r.id() << "  " << r.dir.string() << "  cost " << r.cost << "\n";
        cost += r.cost;
      }
      std::cout << picked.size() << " runs";
      if (o->shard.active())
        std::cout << " of " << plan.runs.size() << " (shard " << o->shard.text() << ")";
      std::cout << ", expected cost " << cost << "\n";
      if (!o->shard.active()) {
        std::vector<double> costs;
        for (const auto& r : plan.runs) costs.push_back(r.cost);
        sim::print_shard_scaling(costs, std::cout);
      }
      return;
    }
    sim::install_interrupt_handlers();
    if (!sharding->only_missing.empty()) {
      status = sim::rerun_missing_compare(self, *o, sharding->only_missing, std::cout, std::cerr);
      return;
    }
    // bad input stops before a folder is made
    const sim::StudyPlan plan = sim::plan_study(*o);
    if (o->out_dir.empty()) o->out_dir = sim::make_run_dir("runs", "compare-" + o->study);
    if (sharding->use_slurm) {
      if (cmd->count("--jobs")) sharding->slurm.jobs = o->jobs;
      status = sim::submit_shards_to_slurm(self, {"compare", o->args, o->out_dir, plan.runs.size()},
                                           sharding->slurm, std::cout, std::cerr);
      return;
    }
    status = sim::run_compare(self, *o, std::cout, std::cerr);
  });
}

// `conesim dataset --frames N --runs M --out DIR`
void add_dataset_command(CLI::App& app, int& status) {
  auto* cmd = app.add_subcommand(
      "dataset",
      "Write labelled training data from closed-loop runs: left camera images with YOLO boxes, "
      "class and instance masks, LiDAR sweeps as PCD with a label per point, a manifest with "
      "poses and intrinsics, and a contact sheet (docs/dataset.md). Exit 0 when written, 1 when "
      "the runs gave too few frames, 2 for bad input");
  auto o = std::make_shared<conesim::sim::DatasetOptions>();
  auto no_lidar = std::make_shared<bool>(false);
  auto fixed_world = std::make_shared<bool>(false);
  cmd->add_option("--frames", o->frames, "Labelled frames in all (default 1000)");
  cmd->add_option("--runs", o->runs,
                  "Runs they come from at least, each giving at most frames/runs (default 10)");
  cmd->add_option("--seed", o->seed, "The dataset's seed: runs, tracks and worlds (default 1)");
  cmd->add_option("--scenario", o->scenario,
                  "Scenario each run starts from, a shipped name or a file (default autocross)");
  cmd->add_option("--set", o->sets, "Override a scenario value in every run: key.path=value");
  cmd->add_option("--every", o->every_s, "Sim seconds between two frames of a run (default 0.5)");
  cmd->add_option("--min-visible", o->min_visible,
                  "Smallest seen fraction of a cone's silhouette that gets a box (default 0.3)");
  cmd->add_option("--min-pixels", o->min_pixels,
                  "Fewest seen pixels of a cone that get a box (default 16)");
  cmd->add_flag("--no-lidar", *no_lidar, "No LiDAR sweeps");
  cmd->add_flag("--fixed-world", *fixed_world,
                "Keep the scenario's clutter, ground and sensors' look (default: drawn per run "
                "from the seed)");
  cmd->add_option("--out", o->out_dir, "Folder to write (default runs/dataset-<UTC stamp>)");
  cmd->callback([=, &status] {
    namespace sim = conesim::sim;
    o->lidar = !*no_lidar;
    o->randomise = !*fixed_world;
    if (o->out_dir.empty()) o->out_dir = sim::make_run_dir("runs", "dataset");
    sim::install_interrupt_handlers();
    try {
      const sim::DatasetSummary s = sim::write_dataset(*o, std::cerr);
      if (sim::interrupt_signal() != 0) {
        std::cerr << "interrupted: " << o->out_dir.string()
                  << " is not complete (no manifest.json; its INCOMPLETE file says so)\n";
        status = 1;
        return;
      }
      std::printf("%d frames from %d runs in %.1f s: %d boxes, %d LiDAR sweeps; %d boxes of "
                  "unhidden cones checked against the segmentation, smallest IoU %.3f, %d below "
                  "0.9\n%s\n",
                  s.frames, s.runs, s.wall_s, s.boxes, s.lidar_sweeps, s.checked_boxes,
                  s.min_box_iou, s.boxes_below_iou, o->out_dir.string().c_str());
      status = s.boxes_below_iou == 0 ? 0 : 1;
    } catch (const conesim::core::InputError&) {
      throw;
    } catch (const std::runtime_error& e) {
      std::cerr << "conesim dataset: " << e.what() << "\n";
      status = 1;
    }
  });
}

// `conesim vehicle inspect FILE --steer RAD`
void add_vehicle_commands(CLI::App& app) {
  auto* vehicle = app.add_subcommand("vehicle", "Vehicle parameter sets");
  vehicle->require_subcommand(1);
  auto* cmd = vehicle->add_subcommand(
      "inspect", "Print the wheel angles and turn radius for a single-track steering angle");
  auto file = std::make_shared<std::string>();
  auto steer = std::make_shared<double>(0.0);
  cmd->add_option("FILE", *file, "Vehicle YAML file, or 'default'")->required();
  cmd->add_option("--steer", *steer, "Single-track steering angle, radians (positive left)")
      ->required();
  cmd->callback([=] {
    const auto p = *file == "default" ? conesim::vehicle_models::VehicleParams{}
                                      : conesim::sim::load_vehicle(*file);
    if (!std::isfinite(*steer) || std::abs(*steer) > p.max_steer_rad)
      throw conesim::core::InputError("--steer", 0,
                                      "expected an angle within the steering limit of +-" +
                                          std::to_string(p.max_steer_rad) + " rad");
    const auto w = conesim::vehicle_models::split_steering(*steer, p);
    const double radius = conesim::vehicle_models::turn_radius_m(*steer, p.wheelbase_m);
    nlohmann::json j = {{"vehicle", p.name},
                        {"steer_rad", *steer},
                        {"ackermann_factor", p.ackermann_factor},
                        {"left_wheel_rad", w.left_rad},
                        {"right_wheel_rad", w.right_rad},
                        {"turn_radius_m",
                         std::isfinite(radius) ? nlohmann::json(radius) : nlohmann::json(nullptr)}};
    std::cout << conesim::sim::json_text(j, 2) << "\n";
  });
}

// `conesim bench sensors`
void add_bench_commands(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Speed figures (medians; the machine's load shows)");
  bench->require_subcommand(1);
  auto* cmd = bench->add_subcommand(
      "sensors", "LiDAR Mrays/s and ms per scan, ms per stereo pair, closed-loop real-time factor");
  auto repeats = std::make_shared<int>(3);
  auto no_loop = std::make_shared<bool>(false);
  cmd->add_option(
         "--repeats", *repeats,
         "Repetitions: closed-loop runs per figure (their median); sensor figures take more")
      ->check(CLI::Range(1, 1000));
  cmd->add_flag("--no-closed-loop", *no_loop, "Skip the closed-loop runs");
  cmd->callback(
      [=] { std::cout << conesim::sim::json_text(conesim::sim::bench_sensors(*repeats, !*no_loop), 2) << "\n"; });

  auto* tracks_cmd = bench->add_subcommand(
      "tracks",
      "Seconds of track validate, info and convert on large layouts (a circuit among "
      "scattered cones, a long circuit, random cones)");
  auto counts = std::make_shared<std::vector<int>>(std::vector<int>{1000, 4000, 10000, 20000});
  auto track_repeats = std::make_shared<int>(3);
  auto keep = std::make_shared<fs::path>();
  tracks_cmd->add_option("--cones", *counts, "Cone counts (comma-separated)")
      ->delimiter(',')
      ->check(CLI::Range(10, 100000));
  tracks_cmd->add_option("--repeats", *track_repeats, "Repetitions (the median is given)")
      ->check(CLI::Range(1, 100));
  tracks_cmd->add_option("--keep", *keep, "Write the layouts into this folder and keep them");
  tracks_cmd->callback([=] {
    std::cout << conesim::sim::json_text(conesim::sim::bench_tracks(*counts, *track_repeats, *keep), 2) << "\n";
  });
  // `conesim bench soak`: many laps in one process, memory and SLAM update time lap by lap
  auto* soak = bench->add_subcommand(
      "soak",
      "A long trackdrive (default: trackdrive-lidar, 100 laps): RSS and SLAM update p99 "
      "lap by lap, lap 10 against the last, the first ten laps against the last ten");
  auto options = std::make_shared<conesim::sim::SoakOptions>();
  soak->add_option("--scenario", options->scenario, "A shipped scenario or file");
  soak->add_option("--laps", options->laps, "Laps to drive")->check(CLI::Range(20, 1000));
  soak->add_option("--seed", options->seed, "The scenario seed");
  soak->add_option("--set", options->sets, "key.path=value, as for conesim run");
  soak->callback([=] { std::cout << conesim::sim::json_text(conesim::sim::bench_soak(*options), 2) << "\n"; });
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conesim: closed-loop Formula Student Driverless simulator"};
  app.set_version_flag("--version", std::string("conesim ") + CONESIM_VERSION);
  app.require_subcommand(1);
  int status = 0;
  add_track_commands(app, status);
  add_run_command(app, status);
  add_view_command(app);
  add_regress_command(app, status, argc, argv);
  add_merge_command(app, status, argc, argv);
  add_slurm_commands(app, status);
  add_compare_command(app, status, argc, argv);
  add_dataset_command(app, status);
  add_vehicle_commands(app);
  add_bench_commands(app);

  // exit 0 (done, passed), 1 (a run that did not pass, rule violations with --strict), 2 (bad
  // input: the message names the file and line, the key or the option) and 3 only for an
  // internal error, a bug to report
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end the parse with success; every mistake on the command line is
    // bad input
    const int code = app.exit(e);
    return code == 0 ? conesim::sim::kExitOk : conesim::sim::kExitBadInput;
  } catch (const conesim::core::InputError& e) {
    std::cerr << e.what() << "\n";
    return conesim::sim::kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "conesim: internal error: " << e.what() << "\n";
    return conesim::sim::kExitInternalError;
  } catch (...) {
    std::cerr << "conesim: internal error: an exception of unknown type\n";
    return conesim::sim::kExitInternalError;
  }
  return status;
}
