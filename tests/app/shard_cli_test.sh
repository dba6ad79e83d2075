#!/usr/bin/env bash
# `conesim regress --shard I/N` and `conesim merge`, end to end on short ground-truth runs: three
# shards merge into the unsharded summary (timing aside); a shard that never ran leaves its runs
# missing (exit 1), and the printed command runs only them and completes the merge; a bad --shard
# is refused with the option named.
set -euo pipefail
conesim="$1"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
study=(acceleration skidpad autocross --seeds 1-2 --no-plot)

"$conesim" regress "${study[@]}" --jobs 2 --out "$tmp/whole" >"$tmp/whole.log" 2>&1 ||
  fail "unsharded regress: $(tail -n 5 "$tmp/whole.log")"
# each shard runs its slice (balanced by expected cost, so not always 2 runs each); the slices
# add up to the 6 runs
declare -A count
for k in 1 2 3; do
  "$conesim" regress "${study[@]}" --jobs 1 --shard "$k/3" --out "$tmp/shard-$k" >"$tmp/s$k.log" 2>&1 ||
    fail "shard $k/3: $(tail -n 5 "$tmp/s$k.log")"
  count[$k]="$(sed -n "s|.*shard $k/3: \([0-9]*\) of 6 runs.*|\1|p" "$tmp/s$k.log" | head -n 1)"
  [ -n "${count[$k]}" ] && [ "${count[$k]}" -ge 1 ] || fail "shard $k/3 runs none of the 6: $(cat "$tmp/s$k.log")"
done
[ $((count[1] + count[2] + count[3])) = 6 ] || fail "the shards ran ${count[*]} runs, not 6 in all"
"$conesim" merge "$tmp"/shard-{1,2,3} --out "$tmp/merged" --expect "$tmp/whole/summary.json" \
  >"$tmp/merge.log" 2>&1 || fail "merge: $(cat "$tmp/merge.log")"
grep -q "same as .* apart from timing" "$tmp/merge.log" || fail "merge does not equal the whole"
grep -q '6 passed, 0 failed' "$tmp/merge.log" || fail "merged table: $(cat "$tmp/merge.log")"
# JUnit: the same testcases, their times aside
diff <(sed 's/time="[^"]*"//g; s/timestamp="[^"]*"//' "$tmp/whole/junit.xml") \
  <(sed 's/time="[^"]*"//g; s/timestamp="[^"]*"//' "$tmp/merged/junit.xml") ||
  fail "merged junit.xml differs from the unsharded one"

# shard 2 died before writing anything: its runs are missing, and the merge says so
rm -rf "$tmp/shard-2"
if "$conesim" merge "$tmp"/shard-{1,2,3} --out "$tmp/m2" >"$tmp/m2.log" 2>&1; then
  fail "a merge with a shard missing exits 0"
fi
[ "$(grep -c '^missing (no result): ' "$tmp/m2.log")" = "${count[2]}" ] ||
  fail "not shard 2's ${count[2]} runs missing: $(cat "$tmp/m2.log")"
rerun="$(grep -A1 'runs missing; run only them' "$tmp/m2.log" | tail -n 1)"
case "$rerun" in *"--only-missing $tmp/m2"*) ;; *) fail "no rerun command: $(cat "$tmp/m2.log")" ;; esac
eval "$rerun" >"$tmp/rerun.log" 2>&1 || fail "the rerun command: $(tail -n 5 "$tmp/rerun.log")"
grep -q "${count[2]} of 6 runs" "$tmp/rerun.log" || fail "the rerun did not run only the ${count[2]} missing runs"
"$conesim" merge "$tmp"/shard-{1,3} "$tmp/m2/rerun-1" --out "$tmp/m3" --expect "$tmp/whole/summary.json" \
  >"$tmp/m3.log" 2>&1 || fail "shards + rerun do not equal the whole: $(cat "$tmp/m3.log")"
grep -q '"missing_runs": \[\]' "$tmp/m2/summary.json" || fail "the rerun did not complete the merge"

# --list with --shard: that shard's runs with their expected cost; the shards' lists make the whole
total=0
for k in 1 2 3; do
  "$conesim" regress "${study[@]}" --shard "$k/3" --list --out "$tmp/list" >"$tmp/list$k.log" 2>&1 ||
    fail "--list --shard $k/3: $(cat "$tmp/list$k.log")"
  grep -q "^${count[$k]} runs of 6 (shard $k/3), expected cost" "$tmp/list$k.log" ||
    fail "--list --shard $k/3 does not list the ${count[$k]} runs the shard ran: $(cat "$tmp/list$k.log")"
  total=$((total + $(grep -c '  cost [0-9.]*$' "$tmp/list$k.log")))
done
[ "$total" = 6 ] || fail "the shards' lists hold $total runs, not 6"

# bad input: the option and what it expects
for bad in 0/4 5/4 x; do
  if "$conesim" regress acceleration --shard "$bad" --list >"$tmp/bad.log" 2>&1; then fail "--shard $bad taken"; fi
  grep -q -- "--shard: expected I/N" "$tmp/bad.log" || fail "--shard $bad: $(cat "$tmp/bad.log")"
done
echo "shards: ok"
