#!/usr/bin/env bash
# Fault matrix for issue 27, "nothing lost on a full disk": every linebake writer run under the
# fault-injection library (faults.c, LD_PRELOAD) with writes failing early, in the middle and near
# the end of what a clean run writes, plus fsync and free-space faults. Each cell asserts
#   (a) no signal (exit < 128), (b) exit 3 (docs/cli.md: an output could not be written),
#   (c) stderr names the output path as given (not a temporary), and
#   (d) the output directory holds what it held before: no output, no *.tmp-* file, and
#   (e) no HDF5 error stack printed.
# Usage: fault_matrix.sh BIN SHIM
#   $FAULT_MATRIX_MD      also write a Markdown table of the cells there
#   $FAULT_MATRIX_FILTER  run only the writers whose name matches this extended regex
#   $FAULT_MATRIX_KEEP    a directory: keep each failed cell's stderr and fault log there
set -u
shim=$(realpath "$2")
# An AddressSanitizer build (the asan preset) needs its runtime first in the preload list.
asan_runtime=$(ldd "$1" 2>/dev/null | awk '/libasan/ {print $3; exit}')
preload="${asan_runtime:+$asan_runtime:}$shim"
repo=$(cd "$(dirname "$0")/../.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# A copy: a rebuild while the matrix runs must not change (or briefly remove) the binary under test.
bin="$tmp/linebake"
cp "$1" "$bin" || exit 1
# Lavapipe's shader cache would be written (and counted) under $HOME: keep it out.
export MESA_SHADER_CACHE_DISABLE=true MESA_GLSL_CACHE_DISABLE=true
limit_s=${FAULT_MATRIX_TIMEOUT:-120}

passed=0
failed=0
rows=()      # Markdown rows
failures=()  # one line per failed cell, for the summary

# --- inputs, made once without faults ---
in="$tmp/in"
mkdir -p "$in"
if ! "$bin" synth convection --scale 0.01 -o "$in/c.binlines" >/dev/null 2>"$tmp/setup.err" ||
   ! "$bin" bake "$in/c.binlines" -o "$in/c.lbc.h5" --assets tubes,voxels,embree \
       >/dev/null 2>>"$tmp/setup.err"; then
  echo "setup failed:"; cat "$tmp/setup.err"; exit 1
fi

# run_cell DIR ERRFILE ENV... -- COMMAND...: runs COMMAND in DIR with the shim and ENV, stdout
# to /dev/null and stderr through a pipe into ERRFILE (the shim leaves fds 1 and 2 alone, and a
# pipe is never a regular file either); sets rc.
run_cell() {
  local dir="$1" err="$2"
  shift 2
  local envs=()
  while [ "$1" != "--" ]; do envs+=("$1"); shift; done
  shift
  (cd "$dir" && timeout "$limit_s" env LD_PRELOAD="$preload" "${envs[@]}" "$@" 2>&1 >/dev/null | cat >"$err"
   exit "${PIPESTATUS[0]}")
  rc=$?
}

# measure NAME COMMAND...: a clean run under the shim; sets total (bytes written to regular
# files, the process's count) or returns 1.
measure() {
  local name="$1"
  shift
  local dir="$tmp/cell"  # the cells' directory: the paths are part of what is written
  rm -rf "$dir"; mkdir -p "$dir/out"
  rm -f "$tmp/count"
  run_cell "$dir" "$tmp/clean.err" LINEBAKE_FAULT_COUNT="$tmp/count" -- "$@"
  rm -rf "$dir"
  total=$(awk 'BEGIN { m = 0 } $2 > m { m = $2 } END { print m }' "$tmp/count" 2>/dev/null)
  if [ "$rc" -ne 0 ] || [ -z "$total" ] || [ "$total" -eq 0 ]; then
    echo "SETUP FAIL: $name: the clean run exited $rc having written ${total:-?} bytes"
    sed 's/^/  err: /' "$tmp/clean.err" | head -5
    return 1
  fi
}

# first_error FILE: the line of stderr worth quoting
# (HDF5's messages hold a newline: a line that starts with "," continues the one before)
first_error() {
  local line joined
  joined=$(awk '/^,/ && n { prev = prev $0; next } { if (n) print prev; prev = $0; n = 1 }
                END { if (n) print prev }' "$1")
  line=$(grep -m1 'linebake: error' <<<"$joined")
  [ -n "$line" ] || line=$(grep -v HDF5-DIAG <<<"$joined" | grep -m1 -i -E 'error|cannot|fail|no space|free')
  [ -n "$line" ] || line=$(grep -m1 . <<<"$joined")
  printf '%s' "${line:-<stderr empty>}" | cut -c1-400
}

# names_output ERRFILE PATH...: stderr names one of the paths itself, not a longer name that
# starts with it (x.vtp.tmp-..., x.lbc.h5.lines-spill...)
names_output() {
  local err="$1" p re
  shift
  for p in "$@"; do
    re=$(printf '%s' "$p" | sed 's/[][\.*^$/]/\\&/g')
    grep -q -E "${re}\\.?([^A-Za-z0-9_.-]|\$)" "$err" && return 0
  done
  return 1
}

# record WRITER FAULT WHY ERRFILE: prints the cell's line and keeps its row
record() {
  local writer="$1" fault="$2" why="$3" err="$4" line
  line=$(first_error "$err")
  if [ -z "$why" ]; then
    passed=$((passed + 1))
    printf '%-34s %-26s PASS\n' "$writer" "$fault"
    rows+=("| \`$writer\` | $fault | PASS | |")
  else
    failed=$((failed + 1))
    printf '%-34s %-26s FAIL %s\n' "$writer" "$fault" "$why"
    printf '%-34s %-26s      stderr: %s\n' "" "" "$line"
    failures+=("$writer | $fault | $why | $line")
    if [ -n "${FAULT_MATRIX_KEEP:-}" ]; then
      local keep
      keep="$FAULT_MATRIX_KEEP/$(printf '%s %s' "$writer" "$fault" | tr -c 'A-Za-z0-9.=-' '_')"
      mkdir -p "$FAULT_MATRIX_KEEP"
      cp "$err" "$keep.stderr"
      [ -f "$tmp/fault.log" ] && cp "$tmp/fault.log" "$keep.faults"
    fi
    rows+=("| \`$writer\` | $fault | **FAIL** | $why: \`$(printf '%s' "$line" | sed 's/|/\\|/g; s/`/'"'"'/g')\` |")
  fi
}

# cell WRITER FAULT OUTPUTS ENV... -- COMMAND...: one faulted run in a fresh directory whose out/
# is where the outputs go (OUTPUTS: space-separated paths relative to the cell directory).
# EXPECT_MESSAGE (a regex stderr must match, besides naming an output) may be set by the caller.
cell() {
  local writer="$1" fault="$2" outputs="$3"
  shift 3
  local dir="$tmp/cell"
  rm -rf "$dir"; mkdir -p "$dir/out"
  local before after
  before=$(cd "$dir" && find out -mindepth 1 | sort)
  rm -f "$tmp/fault.log"
  run_cell "$dir" "$tmp/err" LINEBAKE_FAULT_LOG="$tmp/fault.log" "$@"
  after=$(cd "$dir" && find out -mindepth 1 | sort)
  local reasons=()
  if [ "$rc" -ge 128 ]; then
    if [ "$rc" -eq 137 ] || [ "$rc" -eq 124 ]; then reasons+=("timed out or killed (exit $rc)")
    else reasons+=("killed by signal $((rc - 128)) ($(kill -l $((rc - 128)) 2>/dev/null || echo ?))"); fi
  elif [ "$rc" -ne 3 ]; then
    reasons+=("exit $rc instead of 3")
  fi
  # shellcheck disable=SC2086
  if ! names_output "$tmp/err" $outputs; then
    if grep -q -E '\.tmp-|-spill' "$tmp/err"; then reasons+=("message names a temporary, not the output")
    else reasons+=("message does not name the output"); fi
  fi
  # HDF5's own error stacks are not printed, from whichever thread failed (TBB's threads write
  # a cache's chunks).
  grep -q 'HDF5-DIAG' "$tmp/err" && reasons+=("HDF5 printed its error stack")
  if [ -n "${EXPECT_MESSAGE:-}" ] && ! grep -q -E "$EXPECT_MESSAGE" "$tmp/err"; then
    reasons+=("no message matching '$EXPECT_MESSAGE'")
  fi
  if [ "$before" != "$after" ]; then
    local left tmps
    left=$(comm -13 <(printf '%s\n' "$before") <(printf '%s\n' "$after") | grep . | grep -v -- '\.tmp-' | tr '\n' ' ')
    tmps=$(comm -13 <(printf '%s\n' "$before") <(printf '%s\n' "$after") | grep -c -- '\.tmp-')
    [ -n "$left" ] && reasons+=("left behind: ${left% }")
    [ "$tmps" -gt 0 ] && reasons+=("$tmps temporary file(s) left: $(cd "$dir" && find out -name '*.tmp-*' | head -2 | tr '\n' ' ')")
  fi
  [ -s "$tmp/fault.log" ] || reasons+=("no fault was injected")
  local why=""
  [ ${#reasons[@]} -gt 0 ] && { why=$(IFS=';'; echo "${reasons[*]}"); why=${why//;/; }; }
  record "$writer" "$fault" "$why" "$tmp/err"
}

# writer NAME OUTPUTS COMMAND...: the three byte offsets of a clean run's writes
writer() {
  local name="$1" outputs="$2"
  shift 2
  if [ -n "${FAULT_MATRIX_FILTER:-}" ] && ! [[ "$name" =~ $FAULT_MATRIX_FILTER ]]; then return; fi
  measure "$name" "$@" || { failed=$((failed + 1)); failures+=("$name | clean run | setup failed | $(first_error "$tmp/clean.err")"); return; }
  local early=$((total / 4 < 4096 ? total / 4 : 4096)) middle=$((total / 2)) late=$((total > 512 ? total - 64 : total - total / 8))
  local at
  for at in "early:$early" "middle:$middle" "late:$late"; do
    cell "$name" "${at%%:*} ${at#*:}/$total B" "$outputs" LINEBAKE_FAULT_AFTER="${at#*:}" -- "$@"
  done
}

c="$in/c.binlines"
cache="$in/c.lbc.h5"

echo "== bake"
for assets in tubes voxels embree; do
  for comp in lz4 none; do
    writer "bake --assets $assets --compression $comp" out/x.lbc.h5 \
      "$bin" bake "$c" -o out/x.lbc.h5 --assets "$assets" --compression "$comp"
  done
done

echo "== convert"
for ext in vtp vtk binlines h5 obj csv; do
  writer "convert to .$ext" "out/x.$ext" "$bin" convert "$c" -o "out/x.$ext"
done

echo "== export"
writer "export --glb" out/x.glb "$bin" export "$cache" --glb out/x.glb
writer "export --glb --draco" out/x.glb "$bin" export "$cache" --glb out/x.glb --draco
writer "export --vdb" out/x.vdb "$bin" export "$cache" --vdb out/x.vdb

echo "== render"
small=(--size 64x48 --frame-count 2)
writer "render reference -o x.png" out/x.png \
  "$bin" render "$cache" --technique reference "${small[@]}" -o out/x.png
writer "render embree -o x.pfm" out/x.pfm \
  "$bin" render "$cache" --technique embree "${small[@]}" -o out/x.pfm
writer "render -o x.png --stats s.json" "out/x.png out/s.json" \
  "$bin" render "$cache" --technique reference "${small[@]}" -o out/x.png --stats out/s.json
writer "depth-complexity -o dc.png" out/dc.png \
  "$bin" depth-complexity "$cache" "${small[@]}" -o out/dc.png

echo "== fsync and free space"
if [ -z "${FAULT_MATRIX_FILTER:-}" ] || [[ fsync =~ $FAULT_MATRIX_FILTER ]]; then
  cell "bake --assets tubes" "fsync EIO" out/x.lbc.h5 LINEBAKE_FAULT_FSYNC=1 -- \
    "$bin" bake "$c" -o out/x.lbc.h5 --assets tubes
  for ext in h5 binlines; do
    cell "convert to .$ext" "fsync EIO" "out/x.$ext" LINEBAKE_FAULT_FSYNC=1 -- \
      "$bin" convert "$c" -o "out/x.$ext"
  done
fi
if [ -z "${FAULT_MATRIX_FILTER:-}" ] || [[ statvfs =~ $FAULT_MATRIX_FILTER ]]; then
  # bake sees that 1 MB free cannot hold the cache and refuses first.
  EXPECT_MESSAGE=free cell "bake --assets tubes" "statvfs: 1000000 B free" out/x.lbc.h5 \
    LINEBAKE_FAULT_FREE=1000000 -- "$bin" bake "$c" -o out/x.lbc.h5 --assets tubes
fi

echo "== a file system out of inodes"
# Creating an output's temporary fails with ENOSPC (open with O_CREAT under out/): each writer
# says the system's reason (OpenVDB's own open had said only "could not open ... for writing").
# (glTF's std::ofstream opens through glibc's own calls, which the shim does not see.)
if [ -z "${FAULT_MATRIX_FILTER:-}" ] || [[ create =~ $FAULT_MATRIX_FILTER ]]; then
  create_cell() {
    EXPECT_MESSAGE='No space left on device' cell "$1" "create ENOSPC" "$2" \
      LINEBAKE_FAULT_CREATE_UNDER=out/ -- "${@:3}"
  }
  # (The bake's first file is its lock, <cache>.lock: it fails there, before its HDF5 file.)
  create_cell "bake --assets tubes" out/x.lbc.h5 "$bin" bake "$c" -o out/x.lbc.h5
  for ext in vtp vtk binlines h5 obj csv; do
    create_cell "convert to .$ext" "out/x.$ext" "$bin" convert "$c" -o "out/x.$ext"
  done
  create_cell "export --vdb" out/x.vdb "$bin" export "$cache" --vdb out/x.vdb
  create_cell "render reference -o x.png" out/x.png \
    "$bin" render "$cache" --technique reference "${small[@]}" -o out/x.png
  create_cell "render embree -o x.pfm" out/x.pfm \
    "$bin" render "$cache" --technique embree "${small[@]}" -o out/x.pfm
fi

echo "== run"
# A pipeline writes many files: asserted are no signal, a non-zero exit with a message, and no
# temporary anywhere under its directory. Its steps may run as child processes: each inherits the
# shim and counts its own bytes (the clean run's total is the largest process's).
if [ -z "${FAULT_MATRIX_FILTER:-}" ] || [[ run =~ $FAULT_MATRIX_FILTER ]]; then
  pipeline=(run "$repo/pipelines/ci.json" -o out/ci)
  if measure "run pipelines/ci.json" "$bin" "${pipeline[@]}"; then
    at=$((total / 2))
    dir="$tmp/cell"
    rm -rf "$dir"; mkdir -p "$dir/out"
    rm -f "$tmp/fault.log"
    run_cell "$dir" "$tmp/err" LINEBAKE_FAULT_LOG="$tmp/fault.log" LINEBAKE_FAULT_AFTER="$at" -- \
      "$bin" "${pipeline[@]}"
    reasons=()
    [ "$rc" -ge 128 ] && reasons+=("killed by signal $((rc - 128)) or timed out (exit $rc)")
    [ "$rc" -eq 0 ] && reasons+=("exit 0")
    grep -q . "$tmp/err" || reasons+=("no message")
    tmps=$(find "$dir/out" -name '*.tmp-*' | wc -l)
    [ "$tmps" -gt 0 ] && reasons+=("$tmps temporary file(s) left: $(cd "$dir" && find out -name '*.tmp-*' | head -2 | tr '\n' ' ')")
    [ -s "$tmp/fault.log" ] || reasons+=("no fault was injected")
    why=""
    [ ${#reasons[@]} -gt 0 ] && { why=$(IFS=';'; echo "${reasons[*]}"); why=${why//;/; }; }
    record "run pipelines/ci.json" "middle $at/$total B" "$why" "$tmp/err"
  else
    failed=$((failed + 1))
    failures+=("run pipelines/ci.json | clean run | setup failed | $(first_error "$tmp/clean.err")")
  fi
fi

echo
echo "fault matrix: $passed passed, $failed failed"
if [ ${#failures[@]} -gt 0 ]; then
  echo "failed cells (writer | fault | why | stderr):"
  printf '  %s\n' "${failures[@]}"
fi
if [ -n "${FAULT_MATRIX_MD:-}" ]; then
  {
    echo "| writer | fault (bytes written before it / clean run's total) | result | why, stderr |"
    echo "|---|---|---|---|"
    printf '%s\n' "${rows[@]}"
    echo
    echo "$passed passed, $failed failed (errno ENOSPC unless stated; tests/faults/fault_matrix.sh)."
  } >"$FAULT_MATRIX_MD"
fi
[ "$failed" -eq 0 ]
