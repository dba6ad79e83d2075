#!/usr/bin/env bash
# The SDK end to end, as a team uses it: install it to a fresh prefix, build the example
# plug-ins out of tree with find_package(conesim), run them in the loop; plug-ins that are not
# plug-ins, built against another ABI or refusing their configuration are refused (exit 2, the
# file named, nothing written); one that throws, returns NaN or overruns its time budget ends
# the run with a DNF naming it (one that never returns ends the process, its folder INCOMPLETE
# with the DNF); the reference driver, GraphSLAM and the stereo and LiDAR
# front-ends loaded as plug-ins give the built-in runs' metrics.
# usage: sdk_test.sh CONESIM_BINARY BUILD_DIR SOURCE_DIR TEST_PLUGIN_DIR REFERENCE_DRIVER_SO
#        GRAPH_SLAM_SO STEREO_PERCEPTION_SO LIDAR_PERCEPTION_SO SLAM_BACKENDS_SO
set -uo pipefail
bin="$(realpath "$1")"
build="$(realpath "$2")"
src="$(realpath "$3")"
plugins="$(realpath "$4")"
reference="$(realpath "$5")"
graph="$(realpath "$6")"
stereo="$(realpath "$7")"
lidar="$(realpath "$8")"
backends="$(realpath "$9")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/check_lib.sh"
cd "$work" || exit 1

json() {  # json FILE PYTHON_EXPRESSION_OF_m : prints the value
  python3 -c "import json,sys; m=json.load(open(sys.argv[1])); print($2)" "$1"
}
expect_json() {  # expect_json NAME FILE EXPRESSION EXPECTED
  local got
  got="$(json "$2" "$3")"
  if [ "$got" != "$4" ]; then
    echo "FAIL $1: $3 is '$got', expected '$4'"
    failures=$((failures + 1))
  else
    passed=$((passed + 1))
  fi
}
refused() {  # refused NAME REGEX ARGS... : exit 2, the message matches, no run folder
  local name="$1" regex="$2"
  shift 2
  check "$name" 2 "$bin" run "$@" && expect_text "$name" "$work/err" "$regex"
  if [ -e "$work/runs" ]; then
    echo "FAIL $name: a run folder was made"
    failures=$((failures + 1))
  fi
  rm -rf "$work/runs"
}
dnf() {  # dnf NAME REGEX ARGS... : the run ends, exit 1, with a DNF reason matching REGEX
  local name="$1" regex="$2"
  shift 2
  check "$name" 1 "$bin" run "$@" --no-plot --out "$work/$name"
  expect_json "$name: not completed" "$work/$name/metrics.json" "m['completed']" False
  json "$work/$name/metrics.json" "m['dnf_reason']" >"$work/reason"
  expect_text "$name: reason" "$work/reason" "$regex"
}
hang() {  # hang NAME REGEX ARGS... : a call that never returns ends the process, exit 1, with
          # the DNF on stderr and in INCOMPLETE, and no metrics.json
  local name="$1" regex="$2"
  shift 2
  check "$name" 1 "$bin" run "$@" --no-plot --out "$work/$name"
  if [ -e "$work/$name/metrics.json" ]; then
    echo "FAIL $name: a metrics.json was written"
    failures=$((failures + 1))
  fi
  expect_text "$name: stderr" "$work/err" "^DNF \\($regex"
  if [ -f "$work/$name/INCOMPLETE" ]; then
    expect_text "$name: INCOMPLETE" "$work/$name/INCOMPLETE" "^DNF: $regex"
  else
    echo "FAIL $name: no INCOMPLETE"
    failures=$((failures + 1))
  fi
}

# 1: the SDK installed to a fresh prefix, the examples configured and built against it
check install 0 cmake --install "$build" --prefix "$work/prefix"
for f in include/conesim/sdk.hpp include/conesim/sdk/interfaces.hpp lib/cmake/conesim/conesimConfig.cmake; do
  [ -e "$work/prefix/$f" ] || { echo "FAIL install: no $f"; failures=$((failures + 1)); }
done
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
check configure_examples 0 cmake -S "$src/examples/cpp_plugins" -B "$work/ex" "${generator[@]}" \
  -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$work/prefix"
check build_examples 0 cmake --build "$work/ex"
ex="$work/ex"

# 2: the example driver completes autocross on a generated circuit, clean
check example_driver 0 "$bin" run autocross --set "autonomy.driver=plugin:$ex/libfollow_gap_driver.so" \
  --no-plot --out "$work/driver"
expect_json example_driver_completed "$work/driver/metrics.json" "m['completed']" True
expect_json example_driver_cones "$work/driver/metrics.json" "m['penalties']['cones_hit']" 0
expect_json example_driver_named "$work/driver/metrics.json" "m['autonomy']['driver']" \
  "plugin:follow_gap"
# the same seed gives the same run
"$bin" run autocross --set "autonomy.driver=plugin:$ex/libfollow_gap_driver.so" --no-plot \
  --out "$work/driver2" >/dev/null 2>&1
expect_json example_driver_repeats "$work/driver2/metrics.json" "m['final_time_s']" \
  "$(json "$work/driver/metrics.json" "m['final_time_s']")"

# 3: the example SLAM drives the reference driver through autocross, scored as a lane
check example_slam 0 "$bin" run autocross --set perception=cone_sensor \
  --set "autonomy.slam=plugin:$ex/liblandmark_slam.so" --no-plot --out "$work/slam"
expect_json example_slam_lane "$work/slam/metrics.json" "m['slam_driving']" "plugin:landmark_slam"
expect_json example_slam_map "$work/slam/metrics.json" \
  "m['slam']['plugin:landmark_slam']['map_rmse_m'] < 1.0" True
expect_json example_slam_associations "$work/slam/metrics.json" \
  "m['slam']['plugin:landmark_slam']['da_correct_fraction'] > 0.9" True

# 4: the example perception's cones of each LiDAR sweep are scored and drive autocross
check example_perception 0 "$bin" run autocross \
  --set "autonomy.perception=plugin:$ex/libcluster_perception.so" --no-plot --out "$work/perception"
expect_json example_perception_mode "$work/perception/metrics.json" "m['perception']['mode']" plugin
expect_json example_perception_frames "$work/perception/metrics.json" \
  "m['sensors']['lidar_scans'] > 20 and m['perception']['recall_15m'] > 0.4" True
expect_json example_perception_place "$work/perception/metrics.json" \
  "m['perception']['position_rmse_m'] < 0.1 and m['perception']['precision'] > 0.9" True
expect_json example_perception_colour "$work/perception/metrics.json" \
  "m['perception']['colour_accuracy'] > 0.7" True

# 5: what is not a usable plug-in is refused before anything is written, the file named
refused missing_file "autonomy\.driver: .*nowhere\.so: no such plug-in file" autocross \
  --set autonomy.driver=plugin:nowhere.so
refused no_entry_point "autonomy\.driver: .*libtest_not_a_plugin\.so: no symbol conesim_plugin_entry" \
  autocross --set "autonomy.driver=plugin:$plugins/libtest_not_a_plugin.so"
refused wrong_abi "libtest_wrong_abi_plugin\.so: built against conesim SDK ABI 999, and this conesim .* takes ABI 3" \
  autocross --set "autonomy.driver=plugin:$plugins/libtest_wrong_abi_plugin.so"
refused not_a_library "autonomy\.slam: .*: cannot load the plug-in" acceleration --set perception=cone_sensor \
  --set "autonomy.slam=plugin:$src/README.md"
refused refuses_config "autonomy\.driver\.config: driver plug-in 'faulty' .* refused its configuration: refuse:" \
  autocross --set "autonomy.driver={plugin: $plugins/libtest_faulty_plugin.so, config: {refuse: true}}"
refused unknown_builtin "autonomy\.driver: expected reference or plugin:PATH, got 'magic'" autocross \
  --set autonomy.driver=magic
refused unknown_perception "autonomy\.perception: expected ground_truth, .* or plugin:PATH, got 'radar'" \
  trackdrive-lidar --set autonomy.perception=radar
refused slam_not_offered "autonomy\.slam: .*libfollow_gap_driver\.so: the plug-in 'follow_gap' offers no slam" acceleration \
  --set perception=cone_sensor --set "autonomy.slam=plugin:$ex/libfollow_gap_driver.so"

# 6: a plug-in that fails in the loop ends the run with a DNF naming it
faulty="$plugins/libtest_faulty_plugin.so"
dnf driver_throws "^driver plug-in 'faulty' \(.*\) threw in update: injected fault in update" \
  acceleration --set "autonomy.driver={plugin: $faulty, config: {fault: throw}}"
dnf driver_nan "^driver plug-in 'faulty' \(.*\) returned NaN as steer_rad" \
  acceleration --set "autonomy.driver={plugin: $faulty, config: {fault: nan}}"
# (a call that returns late, 1.5 budgets, but returns: the run ends with its DNF)
dnf driver_slow "^driver plug-in 'faulty' \(.*\) did not return from update within its time budget of 200 ms \(it took [0-9]+ ms\)" \
  acceleration --set "autonomy.driver={plugin: $faulty, time_budget_ms: 200, config: {fault: slow, slow_ms: 300}}"
# (one still running at twice its budget: the process ends)
hang driver_hangs "driver plug-in 'faulty' \(.*\) did not return from update within its time budget of 200 ms \(still running after [0-9]+ ms\)" \
  acceleration --set "autonomy.driver={plugin: $faulty, time_budget_ms: 200, config: {fault: hang}}"
hang slam_hangs "slam plug-in 'faulty' \(.*\) did not return from process within its time budget of 200 ms \(still running" \
  acceleration --set perception=cone_sensor \
  --set "autonomy.slam={plugin: $faulty, time_budget_ms: 200, config: {fault: hang}}"
hang perception_hangs "perception plug-in 'faulty' \(.*\) did not return from on_lidar within its time budget of 200 ms \(still running" \
  acceleration --set "autonomy.perception={plugin: $faulty, time_budget_ms: 200, config: {fault: hang}}"
dnf slam_throws "^slam plug-in 'faulty' \(.*\) threw in process: injected fault" \
  acceleration --set perception=cone_sensor \
  --set "autonomy.slam={plugin: $faulty, config: {fault: throw}}"
dnf slam_nan "^slam plug-in 'faulty' \(.*\) returned NaN as estimate.pose.x_m" \
  acceleration --set perception=cone_sensor \
  --set "autonomy.slam={plugin: $faulty, config: {fault: nan}}"
dnf perception_nan "^perception plug-in 'faulty' \(.*\) returned NaN as a cone's x_m" \
  acceleration --set "autonomy.perception={plugin: $faulty, config: {fault: nan}}"

# the comparisons below are about the figures, not the time a call takes (the budget is tested
# above): their plug-ins get a budget that an instrumented build on a loaded machine keeps to
unhurried="time_budget_ms: 60000"

# 7: the reference driver loaded as a plug-in gives the built-in run's metrics, to the bit
#    (but for the wall-clock timings and the autonomy key naming the plug-in)
#    and the same exit status (whether the scenario's pass criteria hold is not the point here)
"$bin" run trackdrive-graphslam --no-plot --out "$work/builtin" >/dev/null 2>&1
builtin_status=$?
check builtin_as_plugin "$builtin_status" "$bin" run trackdrive-graphslam --no-plot \
  --out "$work/as_plugin" \
  --set "autonomy.driver={plugin: $reference, $unhurried, config: {explore_speed_mps: 9, fast_speed_mps: 16}}"
# the metrics of two runs compared, but for the wall-clock timings, the autonomy key naming the
# plug-ins and what only a built-in back-end reports (its statistics, which estimate it
# reports) or a built-in perception (its mode, and each sensor's own score beside the score of
# what it delivers); the SLAM lane FROM of the first is compared with the lane TO of the second
compare_runs() {  # compare_runs A.json B.json [FROM TO]
  python3 - "$@" <<'PY'
import json, sys
def timing(k):
    return k in ("wall_time_s", "real_time_factor", "autonomy") or k.endswith(("_ms", "_us")) \
        or "_ms_" in k or "_us_" in k or "wall" in k or "cpu" in k
def strip(o):
    if isinstance(o, dict):
        return {k: strip(v) for k, v in o.items() if not timing(k)}
    if isinstance(o, list):
        return [strip(v) for v in o]
    return o
a, b = (strip(json.load(open(f))) for f in sys.argv[1:3])
if len(sys.argv) > 3:
    lane_a, lane_b = sys.argv[3:5]
    for m, lane in ((a, lane_a), (b, lane_b)):
        m["slam"] = {"lane": {k: v for k, v in m["slam"][lane].items()
                              if k not in ("association", "estimate_source", "backend_stats")}}
        m.pop("slam_driving")
if a["perception"]["mode"] != b["perception"]["mode"]:
    for m in (a, b):
        m["perception"] = {k: v for k, v in m["perception"].items()
                           if k not in ("mode", "lidar", "lidar_returned_cones", "stereo")}
        # a built-in LiDAR labels each detection by its points, a plug-in's frame is labelled
        # by matching it to the cones; the two agree on every paired observation (da_correct,
        # da_wrong) but may not on an unpaired duplicate (a cluster mostly of ground points
        # beside a cone), so da_rejected is not compared across the two
        for lane in m.get("slam", {}).values():
            if isinstance(lane, dict):
                lane.pop("da_rejected", None)
diff = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
print("identical" if not diff else "different: " + ", ".join(diff))
for k in ("completed", "dnf_reason"):  # why a run ended, when the two runs' endings differ
    if a.get(k) != b.get(k):
        print(f"  {k}: {a.get(k)!r} against {b.get(k)!r}")
PY
}
compare_runs "$work/builtin/metrics.json" "$work/as_plugin/metrics.json" >"$work/diff"
expect_text builtin_identical "$work/diff" "^identical$"

# 8: GraphSLAM loaded as a plug-in (the driving lane plugin:graph) gives the built-in lane's
#    figures and the same run, to the bit
check graph_as_plugin "$builtin_status" "$bin" run trackdrive-graphslam --no-plot \
  --out "$work/graph_plugin" --set "autonomy.slam={plugin: $graph, $unhurried}"
expect_json graph_plugin_lane "$work/graph_plugin/metrics.json" "m['slam_driving']" "plugin:graph"
compare_runs "$work/builtin/metrics.json" "$work/graph_plugin/metrics.json" graph plugin:graph \
  >"$work/graph_diff"
expect_text graph_identical "$work/graph_diff" "^identical$"

# 8b: EKF SLAM and FastSLAM 2.0 loaded as plug-ins (one library, `backend:` chooses) give the
#     built-in lanes' figures and the same runs, to the bit (FastSLAM: its draws seeded as the
#     built-in lane of its name seeds them)
"$bin" run trackdrive-graphslam --no-plot --out "$work/ekf_builtin" --set slam=ekf >/dev/null 2>&1
check ekf_as_plugin $? "$bin" run trackdrive-graphslam --no-plot --out "$work/ekf_plugin" \
  --set "autonomy.slam={plugin: $backends, $unhurried, config: {backend: ekf}}"
compare_runs "$work/ekf_builtin/metrics.json" "$work/ekf_plugin/metrics.json" ekf \
  plugin:backends >"$work/ekf_diff"
expect_text ekf_identical "$work/ekf_diff" "^identical$"
"$bin" run trackdrive-graphslam --no-plot --out "$work/fs_builtin" --set slam=fastslam2 \
  --set driver.trackdrive_laps=2 >/dev/null 2>&1
check fastslam_as_plugin $? "$bin" run trackdrive-graphslam --no-plot --out "$work/fs_plugin" \
  --set driver.trackdrive_laps=2 --set "autonomy.slam={plugin: $backends, $unhurried, config: {backend: fastslam2}}"
compare_runs "$work/fs_builtin/metrics.json" "$work/fs_plugin/metrics.json" fastslam2 \
  plugin:backends >"$work/fs_diff"
expect_text fastslam_identical "$work/fs_diff" "^identical$"
refused backends_unknown "autonomy\.slam\.config: slam plug-in 'backends' .* refused its configuration: backend: expected one of graph, ekf, fastslam1, fastslam2, odometry, got 'ukf'" \
  trackdrive-graphslam --set "autonomy.slam={plugin: $backends, config: {backend: ukf}}"

# 9: the stereo front-end (detector and tracker) loaded as a perception plug-in given the camera
#    gives the built-in stereo run: the same frames to SLAM, scored the same
"$bin" run autocross-stereo --no-plot --out "$work/stereo_builtin" >/dev/null 2>&1
check stereo_as_plugin $? "$bin" run autocross-stereo --no-plot --out "$work/stereo_plugin" \
  --set "autonomy.perception={plugin: $stereo, $unhurried, sensors: [camera]}"
expect_json stereo_plugin_mode "$work/stereo_plugin/metrics.json" "m['perception']['mode']" plugin
compare_runs "$work/stereo_builtin/metrics.json" "$work/stereo_plugin/metrics.json" \
  >"$work/stereo_diff"
expect_text stereo_identical "$work/stereo_diff" "^identical$"

# 10: the LiDAR front-end (detector and tracker) loaded as a perception plug-in given the LiDAR
#     gives the built-in LiDAR run (two laps: mapping and localisation on GraphSLAM)
"$bin" run trackdrive-lidar --no-plot --out "$work/lidar_builtin" \
  --set driver.trackdrive_laps=2 >/dev/null 2>&1
check lidar_as_plugin $? "$bin" run trackdrive-lidar --no-plot --out "$work/lidar_plugin" \
  --set driver.trackdrive_laps=2 \
  --set "autonomy.perception={plugin: $lidar, $unhurried, sensors: [lidar], config: {model: vlp32c}}"
expect_json lidar_plugin_mode "$work/lidar_plugin/metrics.json" "m['perception']['mode']" plugin
compare_runs "$work/lidar_builtin/metrics.json" "$work/lidar_plugin/metrics.json" \
  >"$work/lidar_diff"
expect_text lidar_identical "$work/lidar_diff" "^identical$"
# a model the plug-in does not know is refused before the run, naming the key
check lidar_plugin_bad_model 2 "$bin" run trackdrive-lidar --no-plot --out "$work/lidar_bad" \
  --set "autonomy.perception={plugin: $lidar, sensors: [lidar], config: {model: vlp17}}"
expect_text lidar_plugin_bad_model_named "$work/err" "model: unknown LiDAR model 'vlp17'"
# a model with fewer rings than the scenario's LiDAR ends the run with a DNF naming the plug-in
check lidar_plugin_wrong_model 1 "$bin" run trackdrive-lidar --no-plot --out "$work/lidar_wrong" \
  --set driver.trackdrive_laps=1 --set "autonomy.perception={plugin: $lidar, sensors: [lidar]}"
expect_json lidar_plugin_wrong_model_dnf "$work/lidar_wrong/metrics.json" \
  "'lidar' in m['dnf_reason'] and 'model vlp16 has 16 rings' in m['dnf_reason']" True

report
