#!/usr/bin/env bash
# End-to-end checks of the `conesim track` commands as a user runs them.
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

report
