#!/usr/bin/env bash
# End-to-end checks of the `conesim track` commands as a user runs them.
# usage: cli_test.sh CONESIM_BINARY TEST_DATA_DIR
set -uo pipefail
bin="$1"
data="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
failures=0
passed=0

check() {  # check NAME EXPECTED_STATUS COMMAND... ; output in $work/out, $work/err
  local name="$1" expected="$2"
  shift 2
  "$@" >"$work/out" 2>"$work/err"
  local status=$?
  if [ "$status" -ne "$expected" ]; then
    echo "FAIL $name: exit $status, expected $expected"
    sed 's/^/  stderr: /' "$work/err" | head -5
    failures=$((failures + 1))
    return 1
  fi
  passed=$((passed + 1))
  return 0
}
expect_text() {  # expect_text NAME FILE REGEX
  if ! grep -Eq -e "$3" "$2"; then
    echo "FAIL $1: $(basename "$2") does not match /$3/"
    head -5 "$2" | sed 's/^/  /'
    failures=$((failures + 1))
  else
    passed=$((passed + 1))
  fi
}

# version and help
check version 0 "$bin" --version && expect_text version "$work/out" '^conesim [0-9]+\.[0-9]+'
check help 0 "$bin" track validate --help && expect_text help "$work/out" '--strict'

# every shared track reads (violations alone do not fail without --strict)
check validate_shared 0 "$bin" track validate "$data"/tracks/*/*.yaml "$data"/tracks/*/*.csv

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

if command -v gnuplot >/dev/null; then
  check plot 0 "$bin" track plot "$data/tracks/fssim/FSG.yaml" --out "$work/fsg.png"
  expect_text plot_png <(head -c 8 "$work/fsg.png" | od -c) 'P   N   G'
fi

echo "$passed passed, $failures failed"
[ "$failures" -eq 0 ]
