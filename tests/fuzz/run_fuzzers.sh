#!/usr/bin/env bash
# Runs the libFuzzer targets of a CONESIM_FUZZ=ON build (`./conesim fuzz` calls it after the
# build). Usage: run_fuzzers.sh BUILD_DIR [--seconds N] [--runs N] [--jobs J] [TARGET...]
#   --seconds N  stop each target after N seconds (default 3600)
#   --runs N     stop each target after N inputs (default: no limit)
#   --jobs J     targets at once (default 1)
#   TARGET...    some of tests/fuzz/targets.txt (default: all)
# Inputs are at most 4 KB (about 100 cones: the readers' logic, not their cost with thousands
# of cones, which tests/tracks measures). Each input may take at most 10 s and the process
# 2 GB (-timeout, -rss_limit_mb); a crash,
# hang, memory blow-up, sanitizer report or a problem the harness reports is a finding, kept as
# BUILD_DIR/fuzz/findings/TARGET/{crash,timeout,oom,leak}-SHA1. Corpora grow in
# BUILD_DIR/fuzz/corpus/TARGET (the seeds: targets.txt, tests/fuzz/seeds/, tests/data/fuzz/).
# Exit status 0 when no target found anything, 1 when one did, 2 for a usage mistake.
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
usage() { sed -n '2,/^set -uo/{/^#/s/^# \{0,1\}//p}' "${BASH_SOURCE[0]}" >&2; exit 2; }

[ $# -ge 1 ] || usage
build_dir="$1"
shift
seconds=3600
runs=-1
jobs=1
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds | --runs | --jobs)
      [ $# -ge 2 ] && [[ "$2" =~ ^[0-9]+$ ]] && [ "$2" -gt 0 ] ||
        { echo "conesim fuzz: $1: expected a whole number > 0, got '${2:-}'" >&2; exit 2; }
      case "$1" in --seconds) seconds="$2" ;; --runs) runs="$2" ;; --jobs) jobs="$2" ;; esac
      shift 2 ;;
    -h | --help) usage ;;
    -*) echo "conesim fuzz: unknown option '$1'" >&2; usage ;;
    *) targets+=("$1"); shift ;;
  esac
done

# the targets and their seed folders
declare -A seeds
known=()
while read -r name dirs; do
  [[ -z "$name" || "$name" == \#* ]] && continue
  known+=("$name")
  seeds[$name]="$dirs"
done <"$here/targets.txt"
[ ${#targets[@]} -eq 0 ] && targets=("${known[@]}")
for t in "${targets[@]}"; do
  [ -n "${seeds[$t]+set}" ] ||
    { echo "conesim fuzz: no target '$t' (targets: ${known[*]})" >&2; exit 2; }
  [ -x "$build_dir/tests/fuzz/fuzz_$t" ] ||
    { echo "conesim fuzz: $build_dir/tests/fuzz/fuzz_$t is not built (CONESIM_FUZZ=ON)" >&2; exit 2; }
done

# one target: libFuzzer on its corpus, then a line of figures from its final statistics
fuzz_one() {
  local t="$1" out="$build_dir/fuzz"
  local corpus="$out/corpus/$t" findings="$out/findings/$t" log="$out/logs/$t.log"
  mkdir -p "$corpus" "$findings" "$out/logs"
  local dirs=("$corpus")
  for d in "tests/fuzz/seeds/$t" "tests/data/fuzz/$t" ${seeds[$t]}; do
    [ -d "$root/$d" ] && dirs+=("$root/$d")
  done
  local start=$SECONDS status
  # ASan keeps the call stack of every allocation it has seen; over 10^5 inputs of a YAML reader
  # that grew the process by 2-5 KB an input (150 MB -> 1 GB in 45 min) and slowed it. Without
  # them a finding still reports where it happened; replaying its input (the fuzz regression
  # test, or the target on the file) shows where the memory came from.
  ASAN_OPTIONS="malloc_context_size=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}" \
  "$build_dir/tests/fuzz/fuzz_$t" -rss_limit_mb=2048 -timeout=10 -max_len=4096 \
    -max_total_time="$seconds" \
    -runs="$runs" -print_final_stats=1 -close_fd_mask=1 -artifact_prefix="$findings/" \
    "${dirs[@]}" >"$log" 2>&1
  status=$?
  local execs rate
  execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
  rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)"
  local verdict="no findings"
  if [ $status -ne 0 ]; then
    verdict="FINDING (exit $status): $(ls -t "$findings" | head -1 | sed "s|^|$findings/|")"
  fi
  printf '%-13s %10s execs %7s/s %6d s  %s\n' "$t" "${execs:-?}" "${rate:-?}" \
    $((SECONDS - start)) "$verdict" >"$out/logs/$t.result"
  [ $status -eq 0 ]
}

# at most `jobs` targets at once; the summary in the order given
echo "conesim fuzz: ${targets[*]}: ${seconds} s each$([ "$runs" -gt 0 ] && echo " or $runs inputs"), $jobs at once; logs in $build_dir/fuzz/logs" >&2
failed=0
running=0
for t in "${targets[@]}"; do
  if [ $running -ge "$jobs" ]; then
    wait -n || failed=1
    running=$((running - 1))
  fi
  fuzz_one "$t" &
  running=$((running + 1))
done
while [ $running -gt 0 ]; do
  wait -n || failed=1
  running=$((running - 1))
done
for t in "${targets[@]}"; do cat "$build_dir/fuzz/logs/$t.result"; done
if [ $failed -ne 0 ]; then
  for t in "${targets[@]}"; do
    grep -q FINDING "$build_dir/fuzz/logs/$t.result" || continue
    echo "--- $t: the end of $build_dir/fuzz/logs/$t.log" >&2
    grep -v '^#\|^INFO\|^stat::' "$build_dir/fuzz/logs/$t.log" | tail -25 >&2
  done
  echo "conesim fuzz: a finding; replay it with $build_dir/tests/fuzz/fuzz_TARGET FILE," \
    "and check the input in as tests/data/fuzz/TARGET/NAME once fixed" >&2
  exit 1
fi
