#!/usr/bin/env bash
# End-to-end checks of `conesim run` on bad input, as a user (or a hostile file) gives it: exit
# 2 with the file and line or the option and key named, nothing written or removed; results
# kept when only a picture fails (issue 20).
# usage: run_cli_test.sh CONESIM_BINARY
set -uo pipefail
bin="$(realpath "$1")"
# the work folder one level down in a private folder, so that a name escaping it ("../x")
# lands where no other program writes (a shared /tmp may hold an x of its own)
top="$(mktemp -d)"
work="$top/work"
mkdir "$work"
trap 'rm -rf "$top"' EXIT
. "$(dirname "$0")/check_lib.sh"
cd "$work" || exit 1
bad() {  # bad NAME REGEX ARGS... : exit 2, the message matches, no runs/ folder made
  local name="$1" regex="$2"
  shift 2
  check "$name" 2 "$bin" run "$@" && expect_text "$name" "$work/err" "$regex"
  expect_missing "$name: no run folder" "$work/runs"
  rm -rf "$work/runs"  # so that the next check stands on its own
}

# 1: whole numbers are never narrowed
bad laps_wrap '^--set: driver\.trackdrive_laps: expected a whole number' \
  trackdrive --set driver.trackdrive_laps=4294967297
bad width_wrap '^--set: sensors\.camera\.width_px: expected a whole number' \
  skidpad --set sensors.camera.width_px=4294967936

# SLAM back-ends and association methods by name
bad slam_backend "^--set: slam\\.drive: expected none or a SLAM back-end \\(graph, ekf, fastslam1, fastslam2, odometry\\), got 'magic'" \
  trackdrive-graphslam --set slam.drive=magic
bad slam_shadow '^--set: slam\.shadow: expected back-ends' trackdrive-graphslam --set 'slam.shadow=[ekf,x]'
bad slam_association '^--set: slam\.association: expected an association method' \
  trackdrive-graphslam --set slam.association=guess

# 2: a time past the clock; 3: referee values checked with the scenario
bad timeout_overflow '^--set: referee\.timeout_skidpad_s: expected at most' \
  skidpad --set referee.timeout_skidpad_s=1e13
bad referee_penalty '^--set: referee\.cone_penalty_s: expected a number >= 0' \
  skidpad --set referee.cone_penalty_s=-5
printf 'event: skidpad\nreferee:\n  stuck_time_s: -1\n' >"$work/ref.yaml"
bad referee_in_file 'ref\.yaml:3: referee\.stuck_time_s: ' "$work/ref.yaml"

# 5: the name is a folder under the output folder, never a path
printf 'name: /tmp/elsewhere\nevent: skidpad\n' >"$work/n.yaml"
bad name_absolute 'n\.yaml:1: name: expected a plain name' "$work/n.yaml"
printf 'name: ../../x\nevent: skidpad\n' >"$work/n2.yaml"
bad name_parent 'n2\.yaml:1: name: expected a plain name' "$work/n2.yaml"
expect_missing name_parent "$work/../x"

# 6: every mistake is exit 2
printf 'event: skidpad\n? [a, b]\n: 1\n' >"$work/k.yaml"
bad complex_key 'k\.yaml:2: ' "$work/k.yaml"
bad seed_float 'seed' skidpad --seed 1e3
bad dump_bogus 'dump' skidpad --dump bogus
bad dump_every_zero 'dump-every' skidpad --dump-every 0
bad unknown_option 'bogus' skidpad --bogus
bad missing_scenario 'SCENARIO' 
printf 'event: %s%s\n' "$(printf '[%.0s' $(seq 600))" "$(printf ']%.0s' $(seq 600))" >"$work/deep.yaml"
bad deep_yaml 'deep\.yaml:1: malformed YAML: nested [0-9]+ levels deep' "$work/deep.yaml"
check no_command 2 "$bin"
check help_is_fine 0 "$bin" run --help

# 7: errors blamed on the option; every 64-bit seed runs
bad set_seed '^--set: seed: expected a whole number' skidpad --set seed=abc
bad set_empty '^--set: driver\.fast_speed_mps: expected a value' skidpad --set driver.fast_speed_mps=
check seed_2_53_plus_1 0 "$bin" run skidpad --seed 9007199254740993 --no-plot --out "$work/big"
expect_text seed_2_53_plus_1 "$work/big/metrics.json" '"seed": 9007199254740993,'

# 8: a duplicate key is a warning with its line; a sensor switched off contradicts perception
printf 'event: skidpad\nevent: acceleration\n' >"$work/d.yaml"
check duplicate_key 0 "$bin" run "$work/d.yaml" --no-plot --out "$work/dup"
expect_text duplicate_key "$work/err" 'warning: .*d\.yaml:2: event: given again \(also on line 1\)'
expect_text duplicate_key "$work/dup/metrics.json" '"event": "acceleration"'
bad lidar_off '^--set: sensors\.lidar\.enabled: false contradicts perception: lidar' \
  trackdrive-lidar --set sensors.lidar.enabled=false
bad camera_off '^--set: sensors\.camera\.enabled: false contradicts perception: stereo' \
  autocross-stereo --set sensors.camera.enabled=false

# 3 and 10: bad input leaves a reused output folder as it was
check first_run 0 "$bin" run skidpad --no-plot --out "$work/reuse"
cp "$work/reuse/metrics.json" "$work/first-metrics.json"
check reuse_bad 2 "$bin" run skidpad --set referee.cone_penalty_s=-5 --out "$work/reuse"
if ! cmp -s "$work/reuse/metrics.json" "$work/first-metrics.json"; then
  echo "FAIL reuse_bad: bad input changed the earlier metrics.json"; failures=$((failures + 1))
fi

# 10: a run that starts removes an earlier metrics.json first, so one that then fails (here a
# folder in the way of trajectory.csv) leaves none that could pass for its result
rm -f "$work/reuse/trajectory.csv" && mkdir -p "$work/reuse/trajectory.csv/in-the-way"
check reuse_fails_after_start 3 "$bin" run skidpad --no-plot --out "$work/reuse"
expect_text reuse_fails_after_start "$work/err" 'internal error'
expect_missing reuse_fails_after_start "$work/reuse/metrics.json"

# 4: results first, pictures after: no gnuplot is a warning, and the verdict stands
check no_gnuplot 0 env PATH=/nonexistent "$bin" run skidpad --out "$work/nognuplot"
expect_text no_gnuplot "$work/err" '^warning: run\.png not written'
expect_text no_gnuplot "$work/nognuplot/metrics.json" '"passed": true'

# 9: a blind cone sensor maps nothing: the map figures are null, not 0, every cone in view is
# missed, and the SLAM criteria fail on null
blind=(--set sensors.cone_sensor.detection_probability_near=0
       --set sensors.cone_sensor.detection_probability_far=0)
check blind_slam 1 "$bin" run acceleration-graphslam --no-plot --out "$work/blind" "${blind[@]}"
expect_text blind_slam "$work/out" '^fail: SLAM map RMSE .*not measured'
expect_text blind_slam "$work/out" '^fail: SLAM correct association fraction .*not measured'
expect_text blind_slam "$work/blind/metrics.json" '"map_rmse_m": null'
expect_text blind_slam "$work/blind/metrics.json" '"da_correct_fraction": null'
expect_text blind_slam "$work/blind/metrics.json" '"map_missed": [1-9][0-9]*,'
expect_text blind_slam "$work/out" '^fail: SLAM map missed fraction of the cones in view 1(\.0+)?, at most'
# a seeing one maps what it passes: at most the second big orange cone of each finish pair
# (0.6 m behind the first; GraphSLAM starts no landmark within 1 m of one it has, so the
# partner seen first in a frame of its own keeps the other out: a known limitation)
check seeing_slam 0 "$bin" run acceleration-graphslam --no-plot --out "$work/seeing"
expect_text seeing_slam "$work/seeing/metrics.json" '"map_missed": [0-2],'
expect_text seeing_slam "$work/seeing/metrics.json" '"map_cones_in_view": [5-9][0-9],'

# an acceleration layout whose braking zone (25 m) is shorter than where the driver stops:
# refused before the run, naming the zone's ends and a speed that fits; that speed runs clean
{
  echo 'tag,x,y,direction,x_variance,y_variance,xy_covariance'
  echo 'car_start,-0.3,0.0,0.0,0.0,0.0,0.0'
  for x in 0 75; do
    echo "big_orange,$x,1.5,0.0,0.0,0.0,0.0"
    echo "big_orange,$x,-1.5,0.0,0.0,0.0,0.0"
  done
  for x in $(seq 5 5 70); do
    echo "blue,$x,1.5,0.0,0.0,0.0,0.0"
    echo "yellow,$x,-1.5,0.0,0.0,0.0,0.0"
  done
  for x in $(seq 80 5 100); do
    echo "orange,$x,1.5,0.0,0.0,0.0,0.0"
    echo "orange,$x,-1.5,0.0,0.0,0.0,0.0"
  done
} >"$work/short_zone.csv"
bad short_braking_zone 'short_zone\.csv: not drivable by this car: the braking zone is 25\.0 m long \(finish gate at \(75\.0, 0\.0\), last cone at \(100\.0, .*acceleration_speed_mps=[0-9]+' \
  acceleration --track "$work/short_zone.csv" --no-plot
fits=$(grep -o 'acceleration_speed_mps=[0-9]*' "$work/err" | cut -d= -f2)
check short_zone_slower 0 "$bin" run acceleration --track "$work/short_zone.csv" --no-plot \
  --set "driver.acceleration_speed_mps=${fits:-0}" --out "$work/slow"
expect_text short_zone_slower "$work/slow/metrics.json" '"passed": true'

# a cone under the car where it starts (a 15 m radius circle with a stray cone on the start):
# refused, naming the cone (EUFS SmallCircle has one)
{
  echo 'tag,x,y,direction,x_variance,y_variance,xy_covariance'
  echo 'car_start,0.0,0.0,0.0,0.0,0.0,0.0'
  for a in $(seq 0 10 350); do
    awk -v a="$a" 'BEGIN { r = 3.14159265 / 180 * a;
      printf "blue,%.3f,%.3f,0.0,0.0,0.0,0.0\n", 12 * sin(r), 15 - 12 * cos(r);
      printf "yellow,%.3f,%.3f,0.0,0.0,0.0,0.0\n", 18 * sin(r), 15 - 18 * cos(r) }'
  done
  echo 'yellow,-1.0,0.3,0.0,0.0,0.0,0.0'
} >"$work/under.csv"
bad cone_under_car 'under\.csv: not drivable by this car: the yellow cone at \(-1\.0, 0\.3\) stands under the car where it starts' \
  trackdrive --track "$work/under.csv" --no-plot

# a layout in surveyed (UTM) coordinates: refused before the run, naming a cone and the bound
{
  echo 'tag,x,y,direction,x_variance,y_variance,xy_covariance,id'
  echo 'car_start,500000.0,5500000.0,0.0,0.0,0.0,0.0,'
  for x in $(seq 0 5 70); do
    echo "blue,$((500000 + x)),5500001.5,0.0,0.0,0.0,0.0,$((1000 + x))"
    echo "yellow,$((500000 + x)),5499998.5,0.0,0.0,0.0,0.0,$((2000 + x))"
  done
} >"$work/utm.csv"
bad far_layout 'utm\.csv: cone 1000 stands at \(500000\.0, 5500001\.5\): a run needs every cone within 2000 m of the origin' \
  autocross --track "$work/utm.csv" --no-plot

report
