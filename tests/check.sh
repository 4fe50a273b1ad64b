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
# Under AddressSanitizer (the asan preset; ldd finds its runtime in the binary) the process holds
# 180-330 MiB of the sanitizer's own at its start (shadow memory, allocator), which counts against
# --memory-budget: checks whose point is a budget sized for a build without it are skipped there
# (check_budget, said and counted), and an LD_PRELOAD library must come after its runtime.
asan_runtime=$(ldd "$bin" 2>/dev/null | awk '/libasan/ {print $3; exit}')
skipped=0
check_budget() {  # check_budget NAME COMMAND...: check, except under AddressSanitizer
  if [ -n "$asan_runtime" ]; then
    skipped=$((skipped + 1))
    echo "SKIP: $1 (a memory budget sized for a build without AddressSanitizer)"
    return
  fi
  check "$@"
}
# A budget that is not the point of its check (a bake slowed to be interrupted): the given one, or
# under AddressSanitizer 1 GiB, room for the sanitizer's own memory.
incidental_budget() { if [ -n "$asan_runtime" ]; then echo 1G; else echo "$1"; fi; }
exit_code() {  # exit_code EXPECTED COMMAND...: passes when the command exits with EXPECTED
  local expected="$1"
  shift
  "$@" >/dev/null 2>"$tmp/err"
  [ $? -eq "$expected" ]
}
