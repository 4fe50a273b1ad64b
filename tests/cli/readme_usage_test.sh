#!/usr/bin/env bash
# The README's Usage block runs as written: extracted from README.md, run line by line, in order,
# in an empty directory with `linebake` on the PATH and a small scale S; every line must exit 0.
# Usage: readme_usage_test.sh LINEBAKE REPO_ROOT [SCALE]
set -u
bin=$(realpath "$1")
root="$2"
scale="${3:-0.01}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/bin" "$tmp/work"
ln -s "$bin" "$tmp/bin/linebake"
# The first ```sh block after "## Usage".
awk '/^## Usage/ {usage = 1} usage && /^```sh/ {inside = 1; next} inside && /^```/ {exit} inside' \
  "$root/README.md" >"$tmp/usage.sh"
lines=$(grep -cv '^\s*$' "$tmp/usage.sh")
[ "$lines" -ge 20 ] || {
  echo "FAIL: the Usage block has $lines lines; it was not found"
  exit 1
}
grep -q '^S=' "$tmp/usage.sh" || {
  echo "FAIL: the Usage block does not set the scale S first"
  exit 1
}
passed=0
failed=0
cd "$tmp/work" || exit 1
export PATH="$tmp/bin:$PATH"
while IFS= read -r line; do
  [[ "$line" =~ ^[[:space:]]*$ ]] && continue
  # The test's own scale replaces the block's.
  [[ "$line" =~ ^S= ]] && line="S=$scale"
  eval "$line" >"$tmp/out" 2>"$tmp/err"
  rc=$?
  if [ $rc -eq 0 ]; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL (exit $rc): $line"
    sed 's/^/  err: /' "$tmp/err" | tail -5
  fi
done <"$tmp/usage.sh"
echo "README Usage: $passed lines passed, $failed failed"
[ "$failed" -eq 0 ]
