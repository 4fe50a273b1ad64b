#!/usr/bin/env bash
# Damaged HDF5 (issue 29): a valid HDF5 line file and a valid cache, each damaged with 4 bytes
# (XOR 0xA5) at every 64th byte of its first 8 KiB and inside every chunk-index and object-header
# structure (found by their signatures in the HDF5 file format specification: TREE, BTHD, BTIN,
# BTLF, FAHD, FADB, EAHD, EAIB, EASB, EADB, OHDR, OCHK). `info` reads the line file, `report` the
# cache, and `render --technique reference` the cache at every 2048th byte and in the chunk
# indices.
# Every run must end with exit 0 and the pristine output (the damage hit bytes nothing reads), or
# exit 2 with an error naming the file; never a signal, never another status. The known crashing
# inputs of the fuzzers (tests/fuzz/known/) are replayed the same way. docs/reliability.md.
set -u
bin="$(readlink -f "$1")"
known="$(cd "$(dirname "$0")/../fuzz/known" && pwd)"
# shellcheck source=tests/check.sh
source "$(dirname "$0")/../check.sh"
cd "$tmp" || exit 1
"$bin" synth aneurysm --scale 0.005 -o a.binlines 2>/dev/null
"$bin" convert a.binlines lines.h5 2>/dev/null
# Large enough that its datasets have several chunks, and so chunk indices (fixed arrays).
"$bin" synth aneurysm --scale 0.02 -o b.binlines 2>/dev/null
"$bin" bake b.binlines -o cache.lbc.h5 --assets tubes >/dev/null 2>&1

# Offsets to damage: every 64th byte below 8 KiB, and 4 (and for indices 12) bytes into each
# structure.
# offsets FILE [SIGNATURE...]: the default signatures are every structure's.
offsets() {
  python3 - "$@" <<'EOF'
import sys
data = open(sys.argv[1], "rb").read()
found = set(range(0, min(8192, len(data) - 4), 64))
signatures = sys.argv[2:] or ["TREE", "BTHD", "BTIN", "BTLF", "FAHD", "FADB", "EAHD", "EAIB",
                              "EASB", "EADB", "OHDR", "OCHK"]
for sig in (s.encode() for s in signatures):
    at = data.find(sig)
    while at >= 0:
        # An object header is checksummed whole: one damage inside tells; an index, two.
        inside = (at + 4,) if sig in (b"OHDR", b"OCHK") else (at + 4, at + 12)
        found.update(o for o in inside if o + 4 <= len(data))
        at = data.find(sig, at + 1)
print("\n".join(map(str, sorted(found))))
EOF
}

# damage FILE OFFSET COMMANDS: copies FILE, damages the copy, runs each linebake command of
# COMMANDS (comma separated) on it and prints "OFFSET COMMAND STATUS NAMED SAME" for each (NAMED:
# the error names the copy; SAME: the output equals the pristine file's).
damage() {
  local file="$1" offset="$2" commands="$3"
  local copy="d$offset-${commands//,/-}-$file" command status named same
  cp "$file" "$copy"
  perl -e 'open(F, "+<", $ARGV[0]) or die; seek(F, $ARGV[1], 0); read(F, $b, 4);
    seek(F, $ARGV[1], 0); print F ($b ^ ("\xA5" x length($b)))' "$copy" "$offset"
  for command in ${commands//,/ }; do
    run "$copy" "$command" >"$copy.out" 2>"$copy.err"
    status=$?
    named=0 same=0
    grep -q "$copy" "$copy.err" && named=1
    cmp -s "$copy.out" "$file.$command.out" && same=1
    echo "$offset $command $status $named $same"
  done
  rm -f "$copy" "$copy.out" "$copy.err"
}
# The outputs compared: the text of info and report without the file's own name and size, and
# the rendered image's bytes.
run() {
  local file="$1" command="$2" status
  case "$command" in
    info | report) "$bin" "$command" "$file" >"$file.text" ;;
    render) "$bin" render "$file" --technique reference --size 48x36 -o "$file.png" >/dev/null ;;
  esac
  status=$?
  case "$command" in
    info | report) grep -v -e "$file" -e bytes -e 'file size' "$file.text" ;;
    render) [ $status -eq 0 ] && cat "$file.png" ;;
  esac
  rm -f "$file.text" "$file.png"
  return $status
}
export bin
export -f damage run

run lines.h5 info >lines.h5.info.out
run cache.lbc.h5 report >cache.lbc.h5.report.out
run cache.lbc.h5 render >cache.lbc.h5.render.out
{
  offsets lines.h5 | sed 's/$/ lines.h5 info/'
  # render reads what report reads and the tubes' data: every 2048th byte and the chunk indices.
  offsets cache.lbc.h5 | awk '{ print $1, "cache.lbc.h5", "report" }'
  offsets cache.lbc.h5 FAHD FADB EAHD EAIB EASB EADB BTHD BTIN BTLF TREE |
    awk '$1 % 2048 == 0 || $1 >= 8192 || $1 % 64 != 0 { print $1, "cache.lbc.h5", "render" }'
} >jobs
awk '{print $2, $1, $3}' jobs | xargs -P 2 -n 3 bash -c 'damage "$0" "$1" "$2"' >results

runs=$(wc -l <results)
signals=$(awk '$3 >= 128' results | wc -l)
other=$(awk '$3 != 0 && $3 != 2 && $3 < 128' results | wc -l)
unnamed=$(awk '$3 == 2 && $4 == 0' results | wc -l)
changed=$(awk '$3 == 0 && $5 == 0' results | wc -l)
refused=$(awk '$3 == 2 && $4 == 1' results | wc -l)
echo "hostile_hdf5: $runs damaged runs: $refused refused naming the file, $((runs - refused -
  signals - other - unnamed - changed)) read only undamaged bytes, $signals signals, $other other" \
  "statuses, $unnamed errors without the file, $changed silently different outputs"
check "no damaged file kills linebake with a signal" test "$signals" -eq 0
check "damage exits 0 or 2" test "$other" -eq 0
check "every error names the damaged file" test "$unnamed" -eq 0
check "an exit 0 gives the pristine output" test "$changed" -eq 0
check "the damage was found (at least one refusal per command)" \
  bash -c "for c in info report render; do awk -v c=\$c '\$2 == c && \$3 == 2' results | grep -q . || exit 1; done"
if [ "$signals$other$unnamed$changed" != 0000 ]; then
  awk '$3 >= 128 || ($3 != 0 && $3 != 2) || ($3 == 2 && $4 == 0) || ($3 == 0 && $5 == 0)' \
    results | head -20 | sed 's/^/  offset command status named same: /'
fi

# The inputs that crashed libhdf5 and libnetcdf under the fuzzers: `info` the line files, `report`
# and `render` (which reads the tubes' chunks) the caches.
for input in "$known"/hdf5/* "$known"/cache/* "$known"/netcdf/*; do
  case "$input" in
    */netcdf/*) copy=known.nc commands=info ;;
    */cache/*) copy=known.h5 commands="report render" ;;
    *) copy=known.h5 commands=info ;;
  esac
  cp "$input" "$copy"
  refused=0
  for command in $commands; do
    case "$command" in
      render) "$bin" render "$copy" --technique reference --size 32x24 -o known.png ;;
      *) "$bin" "$command" "$copy" ;;
    esac >/dev/null 2>known.err
    status=$?
    # A command that reads no damaged part may succeed (report reads no tube data).
    check "$command ${input#"$known"/} exits 0 or 2 (status $status)" \
      test "$status" -eq 0 -o "$status" -eq 2
    [ "$status" -eq 2 ] && refused=1 &&
      check "$command ${input#"$known"/} names the file" grep -q "$copy" known.err
  done
  check "${input#"$known"/} is refused" test "$refused" -eq 1
done

echo "hostile_hdf5: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
