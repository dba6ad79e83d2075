#!/usr/bin/env bash
# End-to-end checks of `conesim compare`: bad input is exit 2 before any run; a tiny study (one
# track, one seed, one lap) writes compare.json, compare.md and compare.html with the theses'
# figures; a run that gives no figures makes the exit status 1 and is named.
# usage: compare_cli_test.sh CONESIM_BINARY
set -uo pipefail
bin="$(realpath "$1")"
data="$(cd "$(dirname "$0")/../data/tracks" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/check_lib.sh"
cd "$work" || exit 1

# bad input: named, exit 2, no folder
check unknown_study 2 "$bin" compare fsg --out "$work/bad"
expect_text unknown_study "$work/err" "expected one of fst, raceup, monash, all, got 'fsg'"
check bad_set 2 "$bin" compare fst --set 'slam.shadow=[graph+no_gps]' --out "$work/bad"
expect_text bad_set "$work/err" "unknown ablation 'no_gps'"
[ -e "$work/bad" ] && { echo "FAIL bad input made a folder"; failures=$((failures + 1)); }

# a tiny FST study: one lap of FSG, one seed, its two conditions
check tiny 0 "$bin" compare fst --track "$data/fssim/FSG.yaml" --seeds 1 \
  --set driver.trackdrive_laps=1 --jobs 2 --out "$work/tiny"
for f in compare.json compare.md compare.html; do
  [ -s "$work/tiny/$f" ] || { echo "FAIL tiny: no $f"; failures=$((failures + 1)); }
done
expect_text tiny_md "$work/tiny/compare.md" '^\| fssim/FSG \| 1 \| [0-9.]+ \| 0.96 \| [0-9.]+ \| 0.38 \| [0-9.]+ \| 0.31 \|'
expect_text tiny_md_assoc "$work/tiny/compare.md" '^\| GraphSLAM, JCBB \| [0-9]+ \| [0-9]+ \| [0-9]+ \| 0\.9[0-9]+ \| 2118 \| 112 \| 0.95 \|'
if command -v python3 >/dev/null; then
  python3 - "$work/tiny/compare.json" <<'PY' || { echo "FAIL tiny_json"; failures=$((failures + 1)); }
import json, sys
c = json.load(open(sys.argv[1]))
assert c["schema"] == "conesim-compare/1"
assert c["studies"] == ["fst"] and c["failed_runs"] == []
assert len(c["runs"]) == 2 and all(r["usable"] for r in c["runs"])
lanes = {s["lane"]: s for s in c["summary"]}
for lane in ["graph", "fastslam1", "fastslam2", "ekf", "odometry", "graph-ml", "graph-jcbb"]:
    s = lanes[lane]
    assert s["runs"] == 1, lane
    assert 0 < s["map_rmse_m"]["median"] < 1.0, (lane, s["map_rmse_m"])
    assert s["update_cpu_ms_median"] > 0, lane
assert lanes["fastslam1"]["thesis"]["map_rmse_m"] == 0.96
assert lanes["graph"]["thesis"]["da_wrong"] == 44
assert lanes["odometry"]["runs_closed"] == 0
titles = [t["title"] for t in c["tables"]]
assert any("Table 4.3" in t for t in titles) and any("loop closure" in t for t in titles)
for t in c["tables"]:
    assert all(len(r) == len(t["header"]) for r in t["rows"]), t["title"]
PY
  passed=$((passed + 1))
fi

# --reuse writes the outputs again from the runs already there, running nothing
cp "$work/tiny/compare.json" "$work/first.json"
check reuse 0 "$bin" compare fst --track "$data/fssim/FSG.yaml" --seeds 1 \
  --set driver.trackdrive_laps=1 --no-plot --reuse --out "$work/tiny"
expect_text reuse "$work/err" '^2 runs reused from'
if command -v python3 >/dev/null; then
  python3 - "$work/first.json" "$work/tiny/compare.json" <<'PY' || { echo "FAIL reuse_same"; failures=$((failures + 1)); }
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
assert a["summary"] == b["summary"] and b["reused_runs"] == 2
PY
  passed=$((passed + 1))
fi

# a run that gives no figures: the layout with a cone under the car is refused (exit 2); the
# comparison goes on with the others, names it and exits 1
check failing_run 1 "$bin" compare monash --track "$data/eufs/SmallCircle.csv" \
  --track "$data/fssim/FSG.yaml" --seeds 1 --set driver.trackdrive_laps=1 --no-plot \
  --out "$work/failing"
expect_text failing_run "$work/out" '^FAILED monash \| clutter \| eufs/SmallCircle \| seed 1 .*exit status 2'
expect_text failing_run_md "$work/failing/compare.md" 'eufs/SmallCircle \| seed 1'
expect_text failing_run_ok "$work/out" '^2 of 4 runs gave figures'
report
