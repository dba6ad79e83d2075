#!/usr/bin/env bash
# End-to-end checks of the `conesim track` and `conesim regress` commands as a user runs them.
# usage: cli_test.sh CONESIM_BINARY TEST_DATA_DIR
set -uo pipefail
bin="$1"
data="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/check_lib.sh"

# version and help
check version 0 "$bin" --version && expect_text version "$work/out" '^conesim [0-9]+\.[0-9]+'
check help 0 "$bin" track validate --help && expect_text help "$work/out" '--strict'

# every shared track reads (violations alone do not fail without --strict), but for the one
# EUFS file with a malformed row as found upstream, which is refused naming its line
shared=()
for f in "$data"/tracks/*/*.yaml "$data"/tracks/*/*.csv; do
  [ "$(basename "$f")" = track_created.csv ] || shared+=("$f")
done
check validate_shared 0 "$bin" track validate "${shared[@]}"
check validate_malformed 2 "$bin" track validate "$data/tracks/eufs/track_created.csv" &&
  expect_text validate_malformed "$work/err" 'track_created.csv:79'

# malformed input: exit 2 and file:line: message
printf 'tag,x,y,direction,x_variance,y_variance,xy_covariance\nblue,1.0,2.0,0,0,0,0\nblue,nan,2.0,0,0,0,0\n' >"$work/nan.csv"
check validate_nan 2 "$bin" track validate "$work/nan.csv"
expect_text validate_nan "$work/err" 'nan\.csv:3: '
printf 'cones_left:\n  - [1.0, 2.0\n' >"$work/broken.yaml"
check validate_broken_yaml 2 "$bin" track validate "$work/broken.yaml"
expect_text validate_broken_yaml "$work/err" 'broken\.yaml:[0-9]+: '
: >"$work/empty.csv"
check validate_empty 2 "$bin" track validate "$work/empty.csv"
expect_text validate_empty "$work/err" 'empty\.csv'
check validate_missing 2 "$bin" track validate "$work/does-not-exist.yaml"
expect_text validate_missing "$work/err" 'does-not-exist\.yaml'
check info_malformed 2 "$bin" track info "$work/nan.csv"
# a file name in another encoding (Latin-1 "Großer.yaml": not UTF-8) and a key with bytes that
# are not text: the JSON output carries them as U+FFFD, rather than the command failing
latin1="$work/Gro$(printf '\337')er.yaml"
cp "$data/tracks/fssim/FSG.yaml" "$latin1"
printf '\377\377key: 1\n' >>"$latin1"
check info_latin1 0 "$bin" track info "$latin1" &&
  python3 -c "import json,sys; j=json.load(open(sys.argv[1])); assert j['name'] == 'Gro\ufffder', j['name']" \
    "$work/out" || { echo "FAIL info_latin1: not valid JSON with the name Gro?er"; failures=$((failures + 1)); }

# generate, validate strictly, info, convert and plot
check generate 0 "$bin" track generate --event trackdrive --seed 7 --out "$work/gen.csv"
check generate_strict 0 "$bin" track validate --strict --event trackdrive "$work/gen.csv"
check generate_again 0 "$bin" track generate --event trackdrive --seed 7 --out "$work/gen2.csv"
if ! cmp -s "$work/gen.csv" "$work/gen2.csv"; then
  echo "FAIL generate_deterministic: the same seed gave different files"; failures=$((failures + 1))
fi
check generate_yaml 0 "$bin" track generate --event autocross --seed 3 --out "$work/gen.yaml"
check generate_skidpad 0 "$bin" track generate --event skidpad --out "$work/skidpad.yaml"
check skidpad_strict 0 "$bin" track validate --strict --event skidpad "$work/skidpad.yaml"
check generate_accel 0 "$bin" track generate --event acceleration --out "$work/accel.csv"
check accel_strict 0 "$bin" track validate --strict --event acceleration "$work/accel.csv"
check generate_bad_ext 2 "$bin" track generate --seed 1 --out "$work/gen.txt"
if [ -e "$work/gen.txt" ]; then echo "FAIL generate_bad_ext: left a file"; failures=$((failures + 1)); fi

# generator profiles: strictly compliant, named profiles only, both directions on request
for profile in hairpins slalom chicanes narrow straight-into-hairpin hard mixed; do
  check "generate_$profile" 0 "$bin" track generate --profile "$profile" --seed 5 \
    --out "$work/p-$profile.csv"
  check "generate_${profile}_strict" 0 "$bin" track validate --strict --event trackdrive \
    "$work/p-$profile.csv"
done
if "$bin" track generate --profile wiggly --seed 1 --out "$work/w.csv" 2>/dev/null; then
  echo "FAIL generate_bad_profile: an unknown profile was accepted"; failures=$((failures + 1))
fi
check generate_cw 0 "$bin" track generate --profile hairpins --direction cw --seed 5 \
  --out "$work/cw.csv"
check generate_ccw 0 "$bin" track generate --profile hairpins --direction ccw --seed 5 \
  --out "$work/ccw.csv"
check generate_wide_hairpins 0 "$bin" track generate --profile hairpins --hairpin-diameter 12 \
  --seed 5 --out "$work/h12.csv"
check generate_wide_hairpins_strict 0 "$bin" track validate --strict "$work/h12.csv"
if cmp -s "$work/cw.csv" "$work/ccw.csv"; then
  echo "FAIL generate_direction: cw and ccw gave the same file"; failures=$((failures + 1))
fi

# corpus: N files named by profile, event and seed, and an index
check corpus 0 "$bin" track corpus --count 4 --seed 10 --profile hard,hairpins \
  --event autocross,trackdrive --out "$work/corpus"
for f in hard-autocross-10.csv hairpins-trackdrive-11.csv hard-autocross-12.csv \
         hairpins-trackdrive-13.csv index.json; do
  if [ ! -s "$work/corpus/$f" ]; then echo "FAIL corpus: no $f"; failures=$((failures + 1)); fi
done
expect_text corpus_index "$work/corpus/index.json" '"lap_time_bound_s": [0-9]'
check corpus_strict 0 "$bin" track validate --strict "$work/corpus/"*.csv

# lap-time bound: JSON, the speed profile as CSV, exit 2 on a malformed file
check laptime 0 "$bin" track laptime "$data/tracks/pacsim/FSG19.yaml" \
  --profile-csv "$work/fsg19_speed.csv"
for key in lap_time_s line_length_m top_speed_mps min_speed_mps grip_fraction; do
  expect_text "laptime_$key" "$work/out" "\"$key\": [0-9]"
done
expect_text laptime_csv "$work/fsg19_speed.csv" '^s_m,speed_mps,x_m,y_m$'
check laptime_skidpad 0 "$bin" track laptime "$work/skidpad.yaml"
expect_text laptime_skidpad_event "$work/out" '"event": "skidpad"'
check laptime_grip 0 "$bin" track laptime "$data/tracks/fssim/FSG.yaml" --grip-fraction 0.8
check laptime_malformed 2 "$bin" track laptime "$work/nan.csv"

check info 0 "$bin" track info "$data/tracks/fssim/FSG.yaml"
for key in cones length_m min_width_m max_spacing_m min_radius_m violations; do
  expect_text "info_$key" "$work/out" "\"$key\""
done
check convert 0 "$bin" track convert "$data/tracks/pacsim/FSG19.yaml" "$work/fsg19.csv"
check convert_back 0 "$bin" track convert "$work/fsg19.csv" "$work/fsg19.yaml"
check convert_read 0 "$bin" track validate "$work/fsg19.yaml"

# convert errors name the target, never the temporary file beside it (issue 20 item 10)
check convert_no_folder 2 "$bin" track convert "$data/tracks/eufs/skidpad.csv" "$work/no/such/x.csv"
expect_text convert_no_folder "$work/err" 'no/such/x\.csv: cannot write'
check convert_bad_ext 2 "$bin" track convert "$data/tracks/eufs/skidpad.csv" "$work/x.txt"
expect_text convert_bad_ext "$work/err" "^$work/x\.txt: unknown extension"
for f in convert_no_folder convert_bad_ext; do
  if grep -q 'partial' "$work/err"; then echo "FAIL $f: names the temporary file"; failures=$((failures + 1)); fi
done
# a UTF-8 byte-order mark is no data; YAML nested absurdly deep is refused as such
printf '\xef\xbb\xbf' >"$work/bom.csv"
cat "$data/tracks/eufs/acceleration.csv" >>"$work/bom.csv"
check bom_csv 0 "$bin" track validate "$work/bom.csv"
printf 'cones_left: %s%s\n' "$(printf '[%.0s' $(seq 600))" "$(printf ']%.0s' $(seq 600))" >"$work/deep.yaml"
check deep_yaml 2 "$bin" track validate "$work/deep.yaml"
expect_text deep_yaml "$work/err" 'deep\.yaml:1: malformed YAML: nested [0-9]+ levels deep'

check plot_no_folder 2 "$bin" track plot "$data/tracks/fssim/FSG.yaml" --out "$work/no/such/x.png"
expect_text plot_no_folder "$work/err" 'x\.png: cannot write: no folder'

if command -v gnuplot >/dev/null; then
  check plot 0 "$bin" track plot "$data/tracks/fssim/FSG.yaml" --out "$work/fsg.png"
  expect_text plot_png <(head -c 8 "$work/fsg.png" | od -c) 'P   N   G'
fi

# regress: a tiny sweep, its three summaries, the baseline and the exit codes
accel="$data/tracks/fssim/acceleration.yaml"
check regress 0 "$bin" regress acceleration --track "$accel" --seeds 1-2 --jobs 2 --no-plot \
  --out "$work/rg"
for f in summary.json junit.xml summary.html acceleration/acceleration-s1/metrics.json \
  acceleration/acceleration-s2/report.html; do
  [ -s "$work/rg/$f" ] || { echo "FAIL regress: no $f"; failures=$((failures + 1)); }
done
expect_text regress_summary "$work/rg/summary.json" '"passed": 2'
if command -v python3 >/dev/null; then
  python3 - "$work/rg/junit.xml" <<'PY' || { echo "FAIL regress_junit"; failures=$((failures + 1)); }
import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
cases = root.findall("./testsuite/testcase")
assert root.tag == "testsuites" and len(cases) == 2, (root.tag, len(cases))
assert all(c.get("classname") == "acceleration" for c in cases)
PY
fi
# the same runs against their own summary: no regression
check regress_baseline 0 "$bin" regress acceleration --track "$accel" --seeds 1-2 --no-plot \
  --out "$work/rg2" --baseline "$work/rg/summary.json"
# a baseline 10 % faster: the runs regressed
python3 - "$work/rg/summary.json" "$work/faster.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
for r in s["runs"]:
    r["best_lap_s"] *= 0.9
    r["final_time_s"] *= 0.9
json.dump(s, open(sys.argv[2], "w"))
PY
check regress_regressed 1 "$bin" regress acceleration --track "$accel" --seeds 1 --no-plot \
  --out "$work/rg3" --baseline "$work/faster.json"
expect_text regress_regressed "$work/out" 'regression: best lap'
expect_text regress_regressed_missing "$work/out" 'missing: acceleration \| acceleration \| seed 2'
# a pass criterion it cannot meet: FAIL with the reason and the threshold
check regress_fail 1 "$bin" regress acceleration --track "$accel" --no-plot --out "$work/rg4" \
  --set pass.max_final_time_s=1
expect_text regress_fail_reason "$work/out" '^ +final time .* over 1'
expect_text regress_fail_junit "$work/rg4/junit.xml" '<failure type="fail" message="final time'
# the corpus: each layout its own event, the malformed one skipped with its reason; nothing runs
check regress_list 0 "$bin" regress --tracks corpus --generated 2 --list --out "$work/rg6"
expect_text regress_list_skidpad "$work/out" '^skidpad \| pacsim/skidpad \| seed 1'
expect_text regress_list_generated "$work/out" '^trackdrive \| generated/trackdrive-s2 \| seed 1'
expect_text regress_list_skipped "$work/out" '^skipped eufs/track_created: .*track_created\.csv:79'
if [ -e "$work/rg6/skidpad" ]; then echo "FAIL regress --list: a run started"; failures=$((failures + 1)); fi
# bad input: exit 2 before any run
check regress_unknown_scenario 2 "$bin" regress no-such-scenario --out "$work/rg5"
check regress_bad_set 2 "$bin" regress acceleration --set driver.no_such_key=1 --out "$work/rg5"
check regress_bad_track 2 "$bin" regress acceleration --track "$work/missing.csv" --out "$work/rg5"
check regress_malformed_track 2 "$bin" regress autocross \
  --track "$data/tracks/eufs/track_created.csv" --out "$work/rg5"
check regress_bad_profile 2 "$bin" regress --generated 1:no-such-profile --list --out "$work/rg5"
expect_text regress_bad_profile "$work/err" 'track generate. failed for seed 1: .*no-such-profile'
check regress_bad_seeds 2 "$bin" regress acceleration --seeds 3-1 --out "$work/rg5"
check regress_bad_tracks 2 "$bin" regress --tracks "$work/no-such-folder" --out "$work/rg5"
check regress_bad_baseline 2 "$bin" regress acceleration --baseline "$work/missing.json" \
  --out "$work/rg5"
if [ -e "$work/rg5/acceleration" ]; then echo "FAIL regress bad input: a run started"; failures=$((failures + 1)); fi

report
