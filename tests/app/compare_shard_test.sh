#!/usr/bin/env bash
# `conesim compare --shard I/N` and `conesim merge` of compare shards, end to end on a tiny study
# (monash: one lap of FSG, seeds 1-2, its two conditions: 4 runs): three shards merge into the
# compare.json, compare.md and compare.html of the unsharded call (timing aside); a shard that
# did not finish gives the runs it finished; a shard that never ran leaves its runs missing
# (exit 1, named), and the printed command runs only them and completes the merge.
# usage: compare_shard_test.sh CONESIM_BINARY
set -euo pipefail
conesim="$(realpath "$1")"
data="$(cd "$(dirname "$0")/../data/tracks" && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
study=(monash --track "$data/fssim/FSG.yaml" --seeds 1-2 --set driver.trackdrive_laps=1 --no-plot)
# what differs between two calls: the command and wall time line of compare.md and compare.html
untimed() { grep -v -e '^`' -e '^<p><code>' "$1"; }

"$conesim" compare "${study[@]}" --jobs 2 --out "$tmp/whole" >"$tmp/whole.log" 2>&1 ||
  fail "unsharded compare: $(tail -n 5 "$tmp/whole.log")"
# shards 1 and 2 at once, then 3
for k in 1 2; do
  "$conesim" compare "${study[@]}" --jobs 1 --shard "$k/3" --out "$tmp/shard-$k" >"$tmp/s$k.log" 2>&1 &
done
wait || fail "shard 1 or 2: $(tail -n 3 "$tmp"/s[12].log)"
"$conesim" compare "${study[@]}" --jobs 1 --shard 3/3 --out "$tmp/shard-3" >"$tmp/s3.log" 2>&1 ||
  fail "shard 3/3: $(tail -n 5 "$tmp/s3.log")"
total=0
for k in 1 2 3; do
  n="$(sed -n "s|^shard $k/3: \([0-9]*\) of 4 runs.*|\1|p" "$tmp/s$k.log")"
  [ -n "$n" ] || fail "shard $k/3 does not say how many of the 4 runs it runs: $(head -n 3 "$tmp/s$k.log")"
  total=$((total + n))
done
[ "$total" = 4 ] || fail "the shards ran $total runs, not 4"
n2="$(sed -n 's|^shard 2/3: \([0-9]*\) of 4 runs.*|\1|p' "$tmp/s2.log")"

"$conesim" merge "$tmp"/shard-{1,2,3} --out "$tmp/merged" --expect "$tmp/whole/compare.json" \
  >"$tmp/merge.log" 2>&1 || fail "merge: $(cat "$tmp/merge.log")"
grep -q "same as .* apart from timing" "$tmp/merge.log" || fail "merge does not equal the whole"
grep -q '^4 of 4 runs gave figures' "$tmp/merge.log" || fail "merge: $(cat "$tmp/merge.log")"
for f in compare.md compare.html; do
  diff <(untimed "$tmp/whole/$f") <(untimed "$tmp/merged/$f") >"$tmp/diff" ||
    fail "merged $f differs from the unsharded one: $(head -n 10 "$tmp/diff")"
done

# a shard killed after its runs, before its compare.json: the runs it finished count
mv "$tmp/shard-1/compare.json" "$tmp/shard-1-compare.json"
"$conesim" merge "$tmp"/shard-{1,2,3} --out "$tmp/unfinished" --expect "$tmp/whole/compare.json" \
  >"$tmp/unfinished.log" 2>&1 || fail "merge with an unfinished shard: $(cat "$tmp/unfinished.log")"
grep -q "did not finish; its runs that wrote metrics.json are taken" "$tmp/unfinished.log" ||
  fail "the unfinished shard is not named: $(cat "$tmp/unfinished.log")"
mv "$tmp/shard-1-compare.json" "$tmp/shard-1/compare.json"

# shard 2 never ran: its runs are missing, named, and the merge exits 1
rm -rf "$tmp/shard-2"
if "$conesim" merge "$tmp"/shard-{1,2,3} --out "$tmp/m2" >"$tmp/m2.log" 2>&1; then
  fail "a merge with a shard missing exits 0"
fi
[ "$(grep -c '^missing (no result): monash' "$tmp/m2.log")" = "$n2" ] ||
  fail "not $n2 runs missing: $(cat "$tmp/m2.log")"
grep -q 'missing: no result' "$tmp/m2/compare.md" || fail "compare.md does not list the missing runs"
python3 - "$tmp/m2/compare.json" "$n2" <<'PY' || fail "compare.json's shards section"
import json, sys
c = json.load(open(sys.argv[1]))
assert len(c["shards"]["missing_runs"]) == int(sys.argv[2]), c["shards"]
assert len(c["failed_runs"]) == int(sys.argv[2])
assert "--only-missing" in c["shards"]["rerun"]
PY
rerun="$(grep -A1 'runs missing; run only them' "$tmp/m2.log" | tail -n 1)"
case "$rerun" in *"compare monash"*"--only-missing $tmp/m2"*) ;; *) fail "no rerun command: $(cat "$tmp/m2.log")" ;; esac
eval "$rerun" >"$tmp/rerun.log" 2>&1 || fail "the rerun command: $(tail -n 5 "$tmp/rerun.log")"
grep -q "^rerun: $n2 of 4 runs" "$tmp/rerun.log" || fail "the rerun did not run only the $n2 missing runs: $(head -n 3 "$tmp/rerun.log")"
grep -q '^4 of 4 runs gave figures' "$tmp/rerun.log" || fail "the rerun's merge is not complete"
"$conesim" merge "$tmp"/shard-{1,3} "$tmp/m2/rerun-1" --out "$tmp/m3" --expect "$tmp/whole/compare.json" \
  >"$tmp/m3.log" 2>&1 || fail "shards + rerun do not equal the whole: $(cat "$tmp/m3.log")"

# --list: a shard's runs with their cost; the whole list with its spread over shards
"$conesim" compare "${study[@]}" --shard 1/3 --list >"$tmp/list.log" 2>&1 || fail "--list --shard: $(cat "$tmp/list.log")"
grep -Eq '^[0-9]+ runs of 4 \(shard 1/3\), expected cost' "$tmp/list.log" || fail "--list --shard: $(cat "$tmp/list.log")"
"$conesim" compare "${study[@]}" --list >"$tmp/list.log" 2>&1 || fail "--list: $(cat "$tmp/list.log")"
grep -Eq '^ +32 +[0-9.]+ +[0-9.]+ +[0-9]+% +1$' "$tmp/list.log" || fail "--list has no spread over shards: $(cat "$tmp/list.log")"
# bad input names the option
if "$conesim" compare monash --shard 4/3 --list >"$tmp/bad.log" 2>&1; then fail "--shard 4/3 taken"; fi
grep -q -- "--shard: expected I/N" "$tmp/bad.log" || fail "--shard 4/3: $(cat "$tmp/bad.log")"
echo "compare shards: ok"
