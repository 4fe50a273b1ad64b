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

# One Python process damages the copies and runs linebake on them, two at a time: a shell per
# damaged copy (cp, perl, grep, cmp) cost as much CPU as linebake itself. For each job it prints
# "OFFSET COMMAND STATUS NAMED SAME" (NAMED: the error names the copy; SAME: the output equals
# the pristine file's). Outputs compared: the text of info and report without the lines naming
# the file or its size, and the rendered image's bytes.
jobs() {
  offsets lines.h5 | sed 's/$/ lines.h5 info/'
  # render reads what report reads and the tubes' data: every 2048th byte and the chunk indices.
  offsets cache.lbc.h5 | awk '{ print $1, "cache.lbc.h5", "report" }'
  offsets cache.lbc.h5 FAHD FADB EAHD EAIB EASB EADB BTHD BTIN BTLF TREE |
    awk '$1 % 2048 == 0 || $1 >= 8192 || $1 % 64 != 0 { print $1, "cache.lbc.h5", "render" }'
}
jobs >jobs
python3 - "$bin" jobs >results <<'EOF2'
import os, subprocess, sys
from concurrent.futures import ThreadPoolExecutor

linebake, job_file = sys.argv[1], sys.argv[2]
pristine = {name: open(name, "rb").read() for name in ("lines.h5", "cache.lbc.h5")}

def output(copy, command):
    """The command's comparable output and its status."""
    if command == "render":
        png = copy + ".png"
        done = subprocess.run([linebake, "render", copy, "--technique", "reference", "--size",
                               "48x36", "-o", png], capture_output=True)
        out = open(png, "rb").read() if done.returncode == 0 else b""
        if os.path.exists(png):
            os.remove(png)
        return done, out
    done = subprocess.run([linebake, command, copy], capture_output=True)
    kept = [line for line in done.stdout.splitlines(keepends=True)
            if copy.encode() not in line and b"bytes" not in line and b"file size" not in line]
    return done, b"".join(kept)

expected = {}
for name, command in (("lines.h5", "info"), ("cache.lbc.h5", "report"),
                      ("cache.lbc.h5", "render")):
    expected[name, command] = output(name, command)[1]

def damage(job):
    offset, name, command = job.split()
    offset = int(offset)
    copy = f"d{offset}-{command}-{name}"
    data = bytearray(pristine[name])
    for i in range(offset, min(offset + 4, len(data))):
        data[i] ^= 0xA5
    with open(copy, "wb") as f:
        f.write(data)
    done, out = output(copy, command)
    named = int(copy.encode() in done.stderr)
    same = int(out == expected[name, command])
    os.remove(copy)
    return f"{offset} {command} {done.returncode if done.returncode >= 0 else 128 - done.returncode} {named} {same}"

with ThreadPoolExecutor(2) as pool:
    for line in pool.map(damage, open(job_file).read().split("\n")[:-1]):
        print(line)
EOF2

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
