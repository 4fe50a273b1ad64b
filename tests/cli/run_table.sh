#!/usr/bin/env bash
# The table-driven CLI contract test: every row of errors.tsv (one command and error class) must
# exit with its code, name the file or option on stderr, write nothing, and stop before any work:
# each command gets an empty working directory that must stay empty, and inputs that would take
# minutes to read ($BIG) must not be read, so a row that runs past LIMIT seconds fails.
# Usage: run_table.sh LINEBAKE [TABLE]
set -u
export BIN
BIN=$(realpath "$1")
table="${2:-$(dirname "$0")/errors.tsv}"
limit=10
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export F="$tmp/fixtures" BIG="synth:clouds"
mkdir -p "$F/dir"
export IN="$F/c.binlines" CACHE="$F/c.lbc.h5" VCACHE="$F/v.lbc.h5" PNG="$F/x.png" PNG2="$F/y.png"
export DIR="$F/dir"
{
  "$BIN" synth aneurysm --scale 0.01 -o "$IN" &&
    "$BIN" bake "$IN" -o "$CACHE" &&
    "$BIN" bake "$IN" -o "$VCACHE" --assets voxels --grid 32 &&
    "$BIN" render "$CACHE" --size 32x24 -o "$PNG" &&
    "$BIN" render "$CACHE" --size 48x32 -o "$PNG2"
} >/dev/null 2>"$tmp/setup.err" || {
  echo "FAIL: fixtures"
  cat "$tmp/setup.err"
  exit 1
}

passed=0
failed=0
row=0
while IFS=$'\t' read -r class code pattern command; do
  case "$class" in '#'* | class | '') continue ;; esac
  row=$((row + 1))
  work="$tmp/work/$row"
  mkdir -p "$work"
  start=$(date +%s%N)
  (cd "$work" && timeout 60 bash -c "$command") >"$tmp/out" 2>"$tmp/err"
  rc=$?
  ms=$((($(date +%s%N) - start) / 1000000))
  problems=()
  [ "$rc" -eq "$code" ] || problems+=("exit $rc, expected $code")
  grep -Eq -- "$pattern" "$tmp/err" || problems+=("stderr does not match /$pattern/")
  left=$(cd "$work" && find . -mindepth 1 | head -3 | tr '\n' ' ')
  [ -z "$left" ] || problems+=("left behind: $left")
  [ "$ms" -lt $((limit * 1000)) ] || problems+=("took $ms ms (work was done)")
  if [ ${#problems[@]} -eq 0 ]; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: $class: $command"
    printf '  %s\n' "${problems[@]}"
    sed 's/^/  err: /' "$tmp/err" | head -5
  fi
done <"$table"
echo "cli contract: $passed passed, $failed failed ($row rows)"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
