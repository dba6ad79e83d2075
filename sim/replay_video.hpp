#pragma once
// `conesim view RUN_DIR --mp4` (issue 16, docs/review.md): the run drawn top-down, frame by
// frame, and encoded to RUN_DIR/replay.mp4 by ffmpeg reading raw RGB frames on a pipe.

#include <filesystem>

#include "sim/replay.hpp"

namespace conesim::sim {

inline constexpr const char* kReplayVideoFile = "replay.mp4";
inline constexpr const char* kReplayChaseVideoFile = "replay-chase.mp4";
inline constexpr const char* kReplayCameraVideoFile = "replay-camera.mp4";

/// What the video shows (`--mp4-view`): the whole run top-down (replay.mp4), a chase camera
/// behind and above the car (replay-chase.mp4), or the recorded left camera frames with their
/// boxes (replay-camera.mp4; needs a run with the stereo camera and --replay).
enum class VideoView { kTop, kChase, kCamera };

struct VideoSettings {
  VideoView view = VideoView::kTop;
  double fps = 15.0;
  /// Even sizes (H.264 in yuv420p halves both).
  int width_px = 960;
  int height_px = 720;
};

/// Draws the whole run top-down (the cones in their class colours, a knocked one hollow from
/// its hit; the true path white and the driving SLAM estimate magenta so far; the car's
/// footprint; the latest LiDAR sweep from replay.bin when the run had --replay; each referee
/// event as a red ring where it happened; a time line with the events as ticks) at `fps`, from
/// the trajectory's first to its last row, and has ffmpeg encode it (H.264, yuv420p).
/// settings.view picks the chase view (the same things in perspective from 7 m behind and 3.5 m
/// above the car, following it) or the camera view (each recorded camera frame, scaled up, with
/// the detected boxes solid in their class colour, labelled with class, track id and range, and
/// the true boxes dashed magenta), each to its own file (kReplayChaseVideoFile,
/// kReplayCameraVideoFile). The camera view of a run without recorded camera frames is refused
/// (core::InputError naming replay.bin) before ffmpeg starts.
/// core::InputError naming the file for a folder that is not a run (read_run_folder), when
/// ffmpeg is missing (CONESIM_FFMPEG names another) or when it fails; the video goes through a
/// partial file renamed at the end, so a failure never leaves a replay.mp4 that looks whole.
std::filesystem::path write_replay_video(const std::filesystem::path& run_dir,
                                         const VideoSettings& settings = {});

}  // namespace conesim::sim
