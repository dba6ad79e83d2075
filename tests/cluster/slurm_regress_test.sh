#!/usr/bin/env bash
# A real single-node Slurm (tests/cluster/slurm_local.sh: munged, slurmctld and slurmd of this
# user, everything in a temporary folder): a sharded regression submitted through
# `conesim regress --slurm` merges into the unsharded summary (timing aside); a shard cancelled
# with scancel leaves its runs missing in the merge, and the printed command completes it; a tiny
# comparison submitted through `conesim compare --slurm` merges into the unsharded compare.json.
# Exit 77 (ctest: skipped) only when this machine cannot run the daemons.
set -euo pipefail
conesim="$1"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
tmp="$(mktemp -d)"
chmod 0755 "$tmp"
cleanup() {
  "$here/slurm_local.sh" stop "$tmp/slurm" || true
  rm -rf "$tmp"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*" >&2
  for f in "$tmp"/slurm/log/slurmctld.log "$tmp"/slurm/log/slurmd.log; do
    [ -f "$f" ] && { echo "--- tail of $f" >&2; tail -n 15 "$f" >&2; }
  done
  exit 1
}
started=$SECONDS
set +e
env_line="$("$here/slurm_local.sh" start "$tmp/slurm")"
code=$?
set -e
[ $code -eq 77 ] && exit 77
[ $code -eq 0 ] || fail "single-node Slurm did not start (exit $code)"
export "${env_line?}"  # SLURM_CONF=...
PATH="$PATH:/usr/sbin"
echo "slurm up after $((SECONDS - started)) s ($SLURM_CONF)"

study=(acceleration skidpad autocross --seeds 1-2 --no-plot)
"$conesim" regress "${study[@]}" --jobs 2 --out "$tmp/whole" >"$tmp/whole.log" 2>&1 ||
  fail "unsharded regress: $(tail -n 5 "$tmp/whole.log")"

# 1. three shards and their merge through Slurm
"$conesim" regress "${study[@]}" --slurm --shards 3 --cpus-per-task 1 --time 10 \
  --out "$tmp/cluster" >"$tmp/submit.log" 2>&1 || fail "submit: $(cat "$tmp/submit.log")"
grep -q '^shards job [0-9]' "$tmp/submit.log" || fail "no job id printed: $(cat "$tmp/submit.log")"
timeout 300 "$conesim" slurm status "$tmp/cluster" --wait >"$tmp/status.log" 2>&1 ||
  fail "the jobs did not all complete: $(cat "$tmp/status.log"; cat "$tmp"/cluster/slurm/*.log)"
grep -q "3 tasks: 3 COMPLETED" "$tmp/status.log" || fail "status: $(cat "$tmp/status.log")"
[ -f "$tmp/cluster/summary.json" ] || fail "the merge job wrote no summary: $(cat "$tmp/cluster/slurm/merge.log")"
"$conesim" merge "$tmp"/cluster/shard-{1,2,3} --out "$tmp/check" --expect "$tmp/whole/summary.json" \
  >"$tmp/check.log" 2>&1 || fail "merged summary differs from the unsharded one: $(cat "$tmp/check.log")"
cmp -s <(sed 's/time="[^"]*"//g; s/timestamp="[^"]*"//' "$tmp/cluster/junit.xml") \
  <(sed 's/time="[^"]*"//g; s/timestamp="[^"]*"//' "$tmp/whole/junit.xml") ||
  fail "the merge job's junit.xml differs from the unsharded one"
echo "sharded through Slurm == unsharded after $((SECONDS - started)) s"

# 2. one shard cancelled before it ran (each task takes every CPU of the node, so task 1 waits
# for task 0): its runs are missing, the rerun command completes them
"$conesim" regress "${study[@]}" --slurm --shards 3 --cpus-per-task "$(nproc)" --time 10 \
  --out "$tmp/cancel" >"$tmp/submit2.log" 2>&1 || fail "submit: $(cat "$tmp/submit2.log")"
array="$(sed -n 's/^shards job //p' "$tmp/submit2.log")"
scancel "${array}_1"
timeout 300 "$conesim" slurm status "$tmp/cancel" --wait >"$tmp/status2.log" 2>&1 && fail "status exits 0 with a task cancelled"
grep -q -E "CANCELLED|1 not reported" "$tmp/status2.log" || fail "status does not show the cancelled task: $(cat "$tmp/status2.log")"
grep -q "runs missing; run only them" "$tmp/cancel/slurm/merge.log" ||
  fail "the merge does not list the cancelled shard's runs: $(cat "$tmp/cancel/slurm/merge.log")"
rerun="$(grep -A1 'runs missing; run only them' "$tmp/cancel/slurm/merge.log" | tail -n 1)"
eval "$rerun" >"$tmp/rerun.log" 2>&1 || fail "the rerun command: $(tail -n 8 "$tmp/rerun.log")"
"$conesim" merge "$tmp"/cancel/shard-{1,2,3} "$tmp/cancel/rerun-1" --out "$tmp/check2" \
  --expect "$tmp/whole/summary.json" >"$tmp/check2.log" 2>&1 ||
  fail "cancelled shard rerun does not give the unsharded summary: $(cat "$tmp/check2.log")"
echo "cancelled shard rerun == unsharded after $((SECONDS - started)) s"

# 3. a tiny comparison (monash, one lap of FSG, seeds 1-2: 4 runs) through `compare --slurm`:
# the merge job writes the unsharded compare.json (timing aside)
data="$(cd "$here/../data/tracks" && pwd)"
cstudy=(monash --track "$data/fssim/FSG.yaml" --seeds 1-2 --set driver.trackdrive_laps=1 --no-plot)
"$conesim" compare "${cstudy[@]}" --jobs 2 --out "$tmp/cwhole" >"$tmp/cwhole.log" 2>&1 ||
  fail "unsharded compare: $(tail -n 5 "$tmp/cwhole.log")"
"$conesim" compare "${cstudy[@]}" --slurm --shards 2 --cpus-per-task 1 --time 10 \
  --out "$tmp/ccluster" >"$tmp/csubmit.log" 2>&1 || fail "compare submit: $(cat "$tmp/csubmit.log")"
timeout 300 "$conesim" slurm status "$tmp/ccluster" --wait >"$tmp/cstatus.log" 2>&1 ||
  fail "the compare jobs did not all complete: $(cat "$tmp/cstatus.log"; cat "$tmp"/ccluster/slurm/*.log)"
[ -f "$tmp/ccluster/compare.json" ] || fail "the merge job wrote no compare.json: $(cat "$tmp/ccluster/slurm/merge.log")"
"$conesim" merge "$tmp"/ccluster/shard-{1,2} --out "$tmp/ccheck" --expect "$tmp/cwhole/compare.json" \
  >"$tmp/ccheck.log" 2>&1 || fail "merged compare differs from the unsharded one: $(cat "$tmp/ccheck.log")"
echo "compare sharded through Slurm == unsharded after $((SECONDS - started)) s"
