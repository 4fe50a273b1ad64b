# Sourced by the shell tests: a temporary directory $tmp (removed at exit), and check/exit_code.
# Set `bin` before sourcing.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
passed=0
failed=0
check() {  # check NAME COMMAND...: passes when the command succeeds
  local name="$1"
  shift
  if "$@" >"$tmp/out" 2>"$tmp/err"; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: $name"
    sed 's/^/  out: /' "$tmp/out" | head -20
    sed 's/^/  err: /' "$tmp/err" | head -20
  fi
}
exit_code() {  # exit_code EXPECTED COMMAND...: passes when the command exits with EXPECTED
  local expected="$1"
  shift
  "$@" >/dev/null 2>"$tmp/err"
  [ $? -eq "$expected" ]
}
