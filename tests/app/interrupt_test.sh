#!/usr/bin/env bash
# End-to-end checks of interruptions and output safety (issue 18): SIGINT or SIGTERM stops a run
# within a second with exit 130 or 143 and a folder that is clearly incomplete (no
# metrics.json, an INCOMPLETE file); an unwritable output folder is refused before the run
# (exit 2, nothing written); a regress interrupted and resumed gives the summary of one that
# was not; a layout whose cone ids are near 2^63 runs like the same layout with small ids.
# usage: interrupt_test.sh CONESIM_BINARY TRACKS_DIR
set -uo pipefail
bin="$(realpath "$1")"
tracks="$(realpath "$2")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/check_lib.sh"
cd "$work" || exit 1
expect() {  # expect NAME CONDITION_TEXT : the condition (a test expression) holds
  local name="$1"
  shift
  if "$@"; then passed=$((passed + 1)); else
    echo "FAIL $name: $*"
    failures=$((failures + 1))
  fi
}
# stop PID SIGNAL [--children]: sends the signal and waits for the process to end; sets got (its
# exit status) and took: the milliseconds from the signal until it was last seen running, less
# the longest time one of its threads (or, with --children, of its child processes' threads,
# each of which it waits for) spent runnable but waiting for a CPU meanwhile
# (/proc/PID/task/TID/schedstat). On a busy machine (other builds, the sanitizer build's suite
# two tests at a time) that wait is the machine's, not the stop's. It is every thread's, not
# only the main one's: a run's main thread ends by joining its SLAM lanes' threads, and while a
# lane finishes the update it is in, the main thread is blocked (not waiting for a CPU) and the
# lane's thread is the one that waits. Time spent running or blocked otherwise (sleeping,
# writing) counts in full. It is polled every 20 ms: on a busy machine the poll itself lags,
# which is why the end is when the process was last seen, not when the poll noticed it gone.
stop() {
  local pid="$1" signal="$2" children="${3:-}" sent seen stat p task run w
  local -A wait0=() wait1=()
  sent=$((${EPOCHREALTIME/./} / 1000))
  seen=$sent
  kill -s "$signal" "$pid"
  while read -r -a stat 2>/dev/null <"/proc/$pid/stat" && [ "${stat[2]}" != Z ]; do
    seen=$((${EPOCHREALTIME/./} / 1000))
    for p in "$pid" $([ -n "$children" ] && pgrep -P "$pid"); do
      for task in "/proc/$p/task/"*; do
        read -r run w _ 2>/dev/null <"$task/schedstat" || continue
        [ -n "${wait0[$task]+set}" ] || wait0[$task]=$w
        wait1[$task]=$w
      done
    done
    sleep 0.02
  done
  wait "$pid"
  got=$?
  local waited=0
  for p in "${!wait1[@]}"; do
    w=$((${wait1[$p]} - ${wait0[$p]}))
    [ "$w" -gt "$waited" ] && waited=$w
  done
  took=$((seen - sent - waited / 1000000))
}

# In the sanitizer build (CONESIM_SANITIZE=ON) LeakSanitizer scans the whole process's memory
# as it ends: seconds on a busy machine, the sanitizer's cost and not the stop's. The timed
# stops skip that scan (leak_check_at_exit=0, which a Release build ignores); the run
# interrupted with --leak-check below keeps it and is not timed.
timed_env=(env "ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}leak_check_at_exit=0")

# interrupt [--leak-check] NAME SIGNAL STATUS SCENARIO ARGS...: starts the run, waits until its
# folder is made and a second more, sends the signal and checks the exit within a second (not
# with --leak-check), its status and the folder
interrupt() {
  local launch=("${timed_env[@]}")
  [ "$1" = --leak-check ] && { launch=(); shift; }
  local name="$1" signal="$2" status="$3"
  shift 3
  local out="$work/$name"
  "${launch[@]}" "$bin" run "$@" --no-plot --out "$out" >"$work/$name.out" 2>"$work/$name.err" &
  local pid=$!
  # the folder is made once the handlers are in place and the input is checked
  for _ in $(seq 300); do
    [ -d "$out" ] && break
    sleep 0.1
  done
  sleep 1
  local got took
  stop "$pid" "$signal"
  expect "$name: exit status $got, expected $status" [ "$got" -eq "$status" ]
  [ ${#launch[@]} -gt 0 ] && expect "$name: stopped in $took ms, at most 1000" [ "$took" -le 1000 ]
  expect_missing "$name: no metrics.json" "$out/metrics.json"
  # trajectory.csv is written as the run goes into a partial file: an unfinished run removes it
  expect_missing "$name: no partial trajectory.csv" "$out/.partial-trajectory.csv"
  expect_missing "$name: no trajectory.csv" "$out/trajectory.csv"
  expect_text "$name" "$out/INCOMPLETE" "^interrupted by $signal at sim time"
  expect_text "$name" "$work/$name.err" "^interrupted by $signal"
}

# 1: Ctrl-C and SIGTERM, also with SLAM threads (a shadow lane) and the LiDAR's worker
interrupt sigint SIGINT 130 trackdrive
interrupt sigterm_slam SIGTERM 143 trackdrive-graphslam --set 'slam.shadow=[ekf]'
interrupt sigint_lidar SIGINT 130 trackdrive-lidar
interrupt --leak-check sigint_lidar_leaks SIGINT 130 trackdrive-lidar

# 2: an output folder that cannot be written is refused before the run, nothing written
if [ "$(id -u)" -ne 0 ]; then
  mkdir -p "$work/readonly" && chmod 555 "$work/readonly"
  ro="$work/readonly"
else
  ro=/proc/self  # a folder even root cannot create files in
fi
check unwritable_out 2 "$bin" run skidpad --no-plot --out "$ro"
expect_text unwritable_out "$work/err" "^$ro: cannot write the results here"
expect_missing unwritable_out "$ro/metrics.json"
check unwritable_regress 2 "$bin" regress skidpad --seeds 1 --out "$ro"
expect_text unwritable_regress "$work/err" "^$ro: cannot write the results here"
# a folder the run would create under a file: refused, nothing made
touch "$work/a-file"
check out_under_file 2 "$bin" run skidpad --no-plot --out "$work/a-file/run"
expect_missing out_under_file "$work/a-file/run"

# 3: regress interrupted once a run has finished, then resumed: the summary of a regress that
# was never interrupted (timing keys aside)
runs=(skidpad acceleration --seeds 1-2 --jobs 1 --no-plot)
check regress_whole 0 "$bin" regress "${runs[@]}" --out "$work/whole"
"$bin" regress "${runs[@]}" --out "$work/cut" >"$work/cut.out" 2>"$work/cut.err" &
pid=$!
for _ in $(seq 600); do
  [ -n "$(find "$work/cut" -name metrics.json 2>/dev/null | head -1)" ] && break
  sleep 0.1
done
kill -s INT "$pid"
wait "$pid"
got=$?
expect "regress_interrupted: exit $got, expected 130" [ "$got" -eq 130 ]
expect_missing regress_interrupted "$work/cut/summary.json"
expect_text regress_interrupted "$work/cut.err" 'interrupted by SIGINT: [0-9]+ of 4 runs finished.*--resume'
check regress_resumed 0 "$bin" regress "${runs[@]}" --out "$work/cut" --resume
expect_text regress_resumed "$work/err" 'runs reused from'
same_summary() {  # the rows of two summary.json files without wall times and folders
  python3 - "$1" "$2" <<'EOF'
import json, sys
def rows(path):
    out = []
    for r in json.load(open(path))["runs"]:
        out.append({k: v for k, v in r.items()
                    if "wall" not in k and "real_time" not in k and k != "dir"})
    return sorted(out, key=lambda r: r["id"])
sys.exit(0 if rows(sys.argv[1]) == rows(sys.argv[2]) else 1)
EOF
}
expect "regress_resumed: the summary of the uninterrupted regress" \
  same_summary "$work/whole/summary.json" "$work/cut/summary.json"
# resuming with other runs is bad input
check resume_other 2 "$bin" regress skidpad --seeds 3 --no-plot --out "$work/cut" --resume
expect_text resume_other "$work/err" 'runs\.json differs'

# compare passes SIGTERM on to its runs: it ends within a second with 143, writes no outputs,
# and leaves no run behind
"${timed_env[@]}" "$bin" compare fst --track "$tracks/fssim/FSG.yaml" --seeds 1 --jobs 2 --no-plot \
  --out "$work/cmp" >"$work/cmp.out" 2>"$work/cmp.err" &
pid=$!
sleep 3
stop "$pid" TERM --children
expect "compare_interrupted: exit $got, expected 143" [ "$got" -eq 143 ]
expect "compare_interrupted: stopped in $took ms, at most 1000" [ "$took" -le 1000 ]
expect_missing compare_interrupted "$work/cmp/compare.json"
expect "compare_interrupted: no run left" [ -z "$(pgrep -f -- "--out $work/cmp/")" ]

# 4: cone ids near 2^63 (below and above it): the same run as with the file's small ids, and
# the ids come out as the file gave them
check convert 0 "$bin" track convert "$tracks/fssim/FSG.yaml" "$work/small.csv"
python3 - "$work/small.csv" "$work/huge.csv" <<'EOF'
import sys
rows = open(sys.argv[1]).read().splitlines()
out = [rows[0]]
for k, line in enumerate(rows[1:]):
    f = line.split(",")
    if f[7] != "":
        f[7] = str(2**63 - 200 + 2 * int(f[7]) + (k % 2))
    out.append(",".join(f))
open(sys.argv[2], "w").write("\n".join(out) + "\n")
EOF
check small_ids 0 "$bin" run autocross --track "$work/small.csv" --no-plot --out "$work/small"
check huge_ids 0 "$bin" run autocross --track "$work/huge.csv" --no-plot --out "$work/huge"
same_run() {  # metrics.json of two runs equal apart from timing and cone ids
  python3 - "$1" "$2" <<'EOF'
import json, re, sys
def clean(v):
    if isinstance(v, dict):
        return {k: clean(x) for k, x in v.items()
                if "wall" not in k and "real_time" not in k and k not in ("cone_id", "cones_hit_ids", "track")}
    if isinstance(v, list):
        return [clean(x) for x in v]
    if isinstance(v, str):
        return re.sub(r"cone [0-9]+", "cone N", v)
    return v
a, b = (clean(json.load(open(p))) for p in sys.argv[1:3])
sys.exit(0 if a == b else 1)
EOF
}
expect "huge_ids: the same metrics as with small ids" \
  same_run "$work/small/metrics.json" "$work/huge/metrics.json"
expect_text huge_ids_below "$work/huge/track.csv" ',92233720368547756[0-9]{2},'
expect_text huge_ids_above "$work/huge/track.csv" ',92233720368547(758[0-9]{2}|759[0-9]{2}|76[0-9]{3}),'

report
