# The checks the end-to-end command tests share; source it after setting $work (a scratch
# folder), then call check and expect_text, and end with report.
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
expect_missing() {  # expect_missing NAME PATH
  if [ -e "$2" ]; then
    echo "FAIL $1: $2 exists"
    failures=$((failures + 1))
  else
    passed=$((passed + 1))
  fi
}
report() {  # the totals; fails when a check failed
  echo "$passed passed, $failures failed"
  [ "$failures" -eq 0 ]
}
