#!/usr/bin/env bash
# linebake-mpi: 1, 2 and 3 ranks (3 oversubscribed on CI's 2 cores) bake a multi-file input into
# caches whose datasets equal the serial bake's (the stored block hashes, and h5diff of the values
# through stock HDF5); the serial linebake renders and reuses them; a corrupt file read by rank 1
# stops every rank, naming the rank and the file, and leaves no file behind; so does a write
# that fails in the collective writing.
# Usage: mpi_test.sh <linebake> <linebake-mpi> <the faults library (tests/faults/faults.c)>
set -u
bin=$(realpath "$1")
mpi=$(realpath "$2")
faults=$(realpath "$3")
. "$(dirname "$0")/check.sh"
# Containers run tests as root, which Open MPI refuses unless told.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export HDF5_PLUGIN_PATH=/usr/lib/x86_64-linux-gnu/hdf5/serial/plugins
cd "$tmp"
mkdir run
# Four parts in three formats; csv has no line count in its header, so it is counted by reading.
"$bin" synth convection --scale 0.01 --seed 1 -o run/part_0.binlines >/dev/null
"$bin" synth convection --scale 0.01 --seed 2 -o run/part_1.h5 >/dev/null
"$bin" synth convection --scale 0.005 --seed 3 -o run/part_2.csv >/dev/null
"$bin" synth convection --scale 0.01 --seed 4 -o run/part_3.binlines >/dev/null
# Every asset linebake-mpi builds; small Embree scenes and tube chunks, so that ranks share
# parts and chunks, and a voxel cap that drops chords.
common=(--assets tubes,voxels,embree --chunk-bytes 4000000 --tube-sides 4 --max-chords 8
  --embree-max-primitives 20000)
options=("${common[@]}" --grid 40)
"$bin" bake 'run/part_*' -o serial.lbc.h5 "${options[@]}" >/dev/null 2>&1

# Every dataset's name and stored hash, and the voxel grid's and Embree curves' descriptions
# (their statistics), in file order.
hashes() { h5dump -A "$1" | grep -E '^ *DATASET|ATTRIBUTE "(xxh3_128_blocks|grid|curves|mesh|lines)"' -A12 |
  grep -E 'DATASET|\(0\):' | tr -s ' '; }
export -f hashes
check "serial cache has several tube chunks" bash -c "h5ls -r serial.lbc.h5 | grep -c chunk_000002"
check "serial cache has several Embree parts" bash -c "h5ls -r serial.lbc.h5 | grep -c part_000003"
check "serial cache has dropped voxel chords" \
  bash -c "'$bin' report --json serial.lbc.h5 | grep -Eq '\"chords_dropped\": [1-9]'"
for n in 1 2 3; do
  check "np $n bakes" mpirun -np "$n" "$mpi" bake 'run/part_*' -o "mpi$n.lbc.h5" "${options[@]}"
  check "np $n: every dataset's hash equals the serial bake's" \
    diff <(hashes serial.lbc.h5) <(hashes "mpi$n.lbc.h5")
  check "np $n: h5diff finds the values equal" bash -c "
    for d in \$(h5ls -r serial.lbc.h5 | awk '/Dataset/ {print \$1}'); do
      h5diff -d 0 serial.lbc.h5 mpi$n.lbc.h5 \$d \$d || exit 1
    done"
  check "np $n: provenance records the ranks" \
    bash -c "'$bin' report --json mpi$n.lbc.h5 | grep -q '\"ranks\": $n'"
  # The line model's memory is the data's, not one offsets' 0 more a rank; CPU time is counted.
  check "np $n: the lines' memory figure is the serial bake's, their CPU time recorded" \
    /usr/bin/python3 -c "
import h5py, json
serial, mpi = (json.loads(h5py.File(f, 'r')['/lines'].attrs['provenance'])
               for f in ('serial.lbc.h5', 'mpi$n.lbc.h5'))
assert mpi['memory_bytes'] == serial['memory_bytes'], (mpi['memory_bytes'], serial['memory_bytes'])
assert mpi['build']['cpu_s'] > 0 and mpi['build']['rss_before_bytes'] > 0, mpi['build']
"
  # Embree's BVH is not built under MPI, but its primitives and parts are known from the plan.
  check "np $n: Embree's provenance gives the serial bake's primitives and parts" \
    /usr/bin/python3 -c "
import h5py, json
serial, mpi = (json.loads(h5py.File(f, 'r')['/assets/embree'].attrs['provenance'])['stats']
               for f in ('serial.lbc.h5', 'mpi$n.lbc.h5'))
assert 'not built' in mpi['bvh'], mpi
assert (mpi['primitives'], mpi['parts']) == (serial['primitives'], serial['parts']) and mpi['parts'] >= 4, (mpi, serial)
"
done
check "h5py (no MPI) reads every dataset of the 3-rank cache equal to the serial one's" \
  /usr/bin/python3 -c "
import h5py, numpy as np
a, b = h5py.File('serial.lbc.h5', 'r'), h5py.File('mpi3.lbc.h5', 'r')
names = []
a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
assert len(names) >= 10, names
for n in names:
    assert np.array_equal(a[n][()], b[n][()]), n
"
check "the serial linebake renders the MPI cache as it renders its own" bash -c "
  '$bin' render mpi3.lbc.h5 --technique ll --size 96x64 -o m.png &&
  '$bin' render serial.lbc.h5 --technique ll --size 96x64 -o s.png && cmp m.png s.png"
check "the serial linebake renders the MPI cache's voxels and Embree buffers as its own" bash -c "
  for t in vrc embree; do
    '$bin' render mpi3.lbc.h5 --technique \$t --size 96x64 -o m\$t.png &&
    '$bin' render serial.lbc.h5 --technique \$t --size 96x64 -o s\$t.png && cmp m\$t.png s\$t.png || exit 1
  done"
check "export reads the MPI cache: the same glTF and VDB bytes" bash -c "
  '$bin' export mpi3.lbc.h5 --glb m.glb --vdb m.vdb && '$bin' export serial.lbc.h5 --glb s.glb --vdb s.vdb &&
  cmp m.glb s.glb && cmp m.vdb s.vdb"
check "a serial bake of the same inputs finds every step of the MPI cache up to date" bash -c "
  '$bin' bake 'run/part_*' -o mpi2.lbc.h5 ${options[*]} 2>&1 | grep -q 'is up to date'"
check "a serial bake with another voxel grid rebuilds the voxels only" bash -c "
  '$bin' bake 'run/part_*' -o mpi2.lbc.h5 ${common[*]} --grid 24 > r.txt 2>&1 &&
  grep -q 'tubes: up to date, reused' r.txt && grep -q 'embree: up to date, reused' r.txt"
check "asking linebake-mpi for rtx fails, saying how to get it" bash -c "
  mpirun -np 2 '$mpi' bake 'run/part_*' -o v.lbc.h5 --assets rtx > v.txt 2>&1
  [ \$? -eq 1 ] && grep -q 'serial linebake' v.txt && [ ! -e v.lbc.h5 ]"
check "linebake-mpi --dry-run is a usage error naming the serial bake" bash -c "
  mpirun -np 2 '$mpi' bake 'run/part_*' -o v.lbc.h5 --dry-run > v.txt 2>&1
  [ \$? -eq 1 ] && grep -q 'ask the serial linebake bake' v.txt && [ ! -e v.lbc.h5 ]"
# A cache as the input without -o is baked in place by the serial bake, which the job does not
# do: refused before any work (it wrote <stem>.lbc.lbc.h5 and locked the input's path).
check "linebake-mpi refuses to add assets to a cache in place" bash -c "
  cp mpi2.lbc.h5 inplace.lbc.h5 && mpirun -np 2 '$mpi' bake inplace.lbc.h5 --assets tubes > ip.txt 2>&1
  [ \$? -eq 1 ] && grep -q 'linebake-mpi does not add assets to a cache in place' ip.txt &&
  ! ls | grep -q 'inplace.lbc.lbc.h5'"
# The job's figures are its own since it began reading, every step's: Table 1 marks them.
check "linebake-mpi's build figures are marked as shared in Table 1" bash -c "
  '$bin' report --markdown mpi2.lbc.h5 > t1.md && grep -q ' \*' t1.md && grep -q 'linebake-mpi.s figures are the job.s' t1.md"
# A budget small enough that the voxel records go to their owners in several waves.
"$bin" synth convection --scale 0.1 --seed 5 -o big.binlines >/dev/null
"$bin" bake big.binlines -o big-serial.lbc.h5 --assets voxels --grid 256 >/dev/null 2>&1
check_budget "np 2 within a small budget: the serial bake's voxels, exchanged in waves" bash -c "
  mpirun -np 2 '$mpi' bake big.binlines -o big-mpi.lbc.h5 --assets voxels --grid 256 \
    --memory-budget 80M > /dev/null &&
  diff <(hashes big-serial.lbc.h5) <(hashes big-mpi.lbc.h5) &&
  '$bin' report --json big-mpi.lbc.h5 | grep -Eq '\"exchange_waves\": ([2-9]|[1-9][0-9])'"

# Every rank within its budget with tubes and voxels: the heap the tubes freed is given back
# before the voxel exchange (it had stayed resident: 132 MiB a rank under 128M, 2026-12-01).
"$bin" synth turbulence --scale 0.2 --seed 3 -o turb.binlines >/dev/null 2>&1
check_budget "np 2, tubes and voxels: every rank's peak within its budget" bash -c "
  mpirun -np 2 '$mpi' bake turb.binlines -o turb-mpi.lbc.h5 --assets tubes,voxels --grid 256 \
    --memory-budget 128M > /dev/null &&
  '$bin' report --json turb-mpi.lbc.h5 | python3 -c '
import json, sys
voxels = json.load(sys.stdin)[0][\"assets\"][\"voxels\"]
ranks = voxels[\"stats\"][\"rank_figures\"]
peaks = [r[\"peak_rss_bytes\"] for r in ranks]
assert len(peaks) == 2 and all(0 < p <= 128 << 20 for p in peaks), peaks
'"

# Hundreds of small tube chunks: a rank makes a chunk's datasets when a rank reaches it and
# closes them once no rank will write to it again (all were made up front and held to the end,
# each small one's bytes kept raw by its hash piece: 147 MiB a rank under 64M, 2026-12-01).
"$bin" bake big.binlines -o chunks-serial.lbc.h5 --assets tubes --chunk-bytes 500000 >/dev/null 2>&1
check_budget "np 3, 304 small tube chunks under 64M: the serial bake's tubes, every rank within its budget" bash -c "
  [ \$(h5ls chunks-serial.lbc.h5/assets/tubes | grep -c chunk_) -gt 300 ] &&
  mpirun -np 3 '$mpi' bake big.binlines -o chunks-mpi.lbc.h5 --assets tubes --chunk-bytes 500000 \
    --memory-budget 64M > /dev/null &&
  diff <(hashes chunks-serial.lbc.h5) <(hashes chunks-mpi.lbc.h5) &&
  '$bin' report --json chunks-mpi.lbc.h5 | python3 -c '
import json, sys
ranks = json.load(sys.stdin)[0][\"assets\"][\"tubes\"][\"stats\"][\"rank_figures\"]
peaks = [r[\"peak_rss_bytes\"] for r in ranks]
assert len(peaks) == 3 and all(0 < p <= 64 << 20 for p in peaks), peaks
'"

# A VTP (read whole) past what each rank's budget leaves is refused while it is read, naming it.
"$bin" convert big.binlines -o big.vtp >/dev/null 2>&1
check "np 2: a VTP past the budget is refused while it is read (exit 4), no cache" bash -c "
  mpirun -np 2 '$mpi' bake big.vtp -o vtp-mpi.lbc.h5 --assets tubes --memory-budget 60M > vtp.txt 2>&1
  [ \$? -eq 4 ] && grep -q 'big.vtp: vtp is read whole: at Piece' vtp.txt && [ ! -e vtp-mpi.lbc.h5 ]"

# More ranks than lines: two lines on three ranks leave one rank with nothing to write.
printf 'line_id,x,y,z\n0,0,0,0\n0,1,0,0\n0,1,1,0\n1,0,0,1\n1,0,1,1\n1,1,1,2\n' > two.csv
"$bin" bake two.csv -o two-serial.lbc.h5 >/dev/null 2>&1
check "three ranks, two lines: the serial bake's datasets" bash -c "
  mpirun -np 3 '$mpi' bake two.csv -o two-mpi.lbc.h5 > /dev/null &&
  diff <(h5dump -A two-serial.lbc.h5 | grep -A12 xxh3_128_blocks) \
       <(h5dump -A two-mpi.lbc.h5 | grep -A12 xxh3_128_blocks) > /dev/null &&
  [ \$(h5dump -A two-mpi.lbc.h5 | grep -c xxh3_128_blocks) -ge 5 ]"

# Far-off lines (lines/origin.hpp): the parts moved by 5e6 and baked at --origin auto, which every
# rank finds alone (the first point of the first file); the MPI cache's datasets and metadata are
# the serial bake's.
mkdir far
for f in run/part_*; do
  "$bin" convert "$f" -o near.csv >/dev/null 2>&1
  awk -F, -v OFS=, 'NR > 1 { $2 = sprintf("%.9f", $2 + 5000000); $3 = sprintf("%.9f", $3 + 5000000) } 1' \
    near.csv > "far/$(basename "${f%.*}").csv"
done
"$bin" bake 'far/part_*' -o far-serial.lbc.h5 --origin auto >/dev/null 2>&1
check "np 3 at --origin auto: the serial bake's datasets and origin" bash -c "
  mpirun -np 3 '$mpi' bake 'far/part_*' -o far-mpi.lbc.h5 --origin auto > /dev/null &&
  diff <(hashes far-serial.lbc.h5) <(hashes far-mpi.lbc.h5) &&
  '$bin' info far-mpi.lbc.h5 | grep -E '^origin +5000' &&
  diff <('$bin' info far-serial.lbc.h5 | grep -E '^(origin|world)') \
       <('$bin' info far-mpi.lbc.h5 | grep -E '^(origin|world)')"

check "one file: the serial bake finds the MPI cache up to date (same identity)" bash -c "
  mpirun -np 2 '$mpi' bake run/part_0.binlines -o one.lbc.h5 > /dev/null &&
  '$bin' bake run/part_0.binlines -o one.lbc.h5 2>&1 | grep -q 'is up to date'"

# Files whose attributes differ (convection's curvature, the aneurysm's vorticity) make no one
# line set: refused as the serial bake refuses them, at any rank count (they baked, the
# vorticity column holding curvature values).
mkdir mixed
cp run/part_0.binlines mixed/a.binlines
"$bin" synth aneurysm --scale 0.01 -o mixed/b.binlines >/dev/null 2>&1
for n in 1 2; do
  mpirun -np "$n" "$mpi" bake 'mixed/*.binlines' -o mixed.lbc.h5 >mixed/out$n.txt 2>&1
  code=$?
  check "np $n: files with other attributes exit 2" test "$code" -eq 2
  check "np $n: the error names the file and both attribute lists" \
    grep -q "mixed/b.binlines: its attributes \[vorticity\], line attributes \[\] differ from the first input's (mixed/a.binlines: \[curvature\], \[\])" mixed/out$n.txt
done
check "no mixed cache is left" bash -c "! ls -a | grep -E '^mixed\.lbc\.h5'"

# What the serial bake refuses before it writes, linebake-mpi refuses too (it had baked lines too
# small for float32 tubes, and started writing onto a file system without room for the cache).
printf 'line_id,x,y,z\n0,0,0,0\n0,1e-20,0,0\n0,2e-20,0,0\n' > tiny.csv
for n in 1 2; do
  mpirun -np "$n" "$mpi" bake tiny.csv -o tiny.lbc.h5 --assets tubes,embree >tiny$n.txt 2>&1
  code=$?
  check "np $n: lines spanning 2e-20 units exit 2 as in the serial bake" test "$code" -eq 2
  check "np $n: the error says the span" grep -q "tiny.csv: the lines span 2e-20 units" tiny$n.txt
done
mkdir space
mpirun -np 2 -x LD_PRELOAD="$faults" -x LINEBAKE_FAULT_FREE=1000000 "$mpi" bake run/part_0.binlines \
  -o space/s.lbc.h5 >space/out.txt 2>&1
code=$?
check "np 2: 1 MB free (statvfs) is refused before writing, exit 3" test "$code" -eq 3
check "the refusal gives the figures and the way past it" \
  grep -q "space/s.lbc.h5: needs about .* free on space; --no-space-check bakes anyway" space/out.txt
check "nothing is left in the directory" bash -c "[ -z \"\$(ls -A space | grep -v out.txt)\" ]"
mpirun -np 2 -x LD_PRELOAD="$faults" -x LINEBAKE_FAULT_FREE=1000000 "$mpi" bake run/part_0.binlines \
  -o space/s.lbc.h5 --no-space-check >/dev/null 2>&1
check "np 2: --no-space-check bakes anyway" test -s space/s.lbc.h5

# Rank 1 of 2 reads the end of the input: part_3 is cut short there.
mkdir bad
cp run/* bad/
size=$(stat -c %s bad/part_3.binlines)
truncate -s $((size - 100)) bad/part_3.binlines
mpirun -np 2 "$mpi" bake 'bad/part_*' -o bad.lbc.h5 >out.txt 2>&1
code=$?
check "a corrupt file on rank 1 exits 2" test "$code" -eq 2
check "the error names rank 1 and the file" grep -q "rank 1: bad/part_3.binlines" out.txt
check "no cache, temporary or spill file is left" \
  bash -c "! ls -a | grep -E 'bad\.lbc\.h5|\.tmp-'"

# A write that fails inside the collective writing on one rank (a file size limit on rank 1
# standing in for a full disk; its spill fits, the tubes do not) cannot be agreed on: that rank
# ends the job with exit 3 at once (it hung before: it closed the file collectively while rank 0
# waited in the next write), and neither the cache, its temporary nor a spill file is left.
mkdir full
timeout 120 mpirun -np 2 --mca btl self,tcp bash -c \
  "trap '' XFSZ; [ \$OMPI_COMM_WORLD_RANK = 1 ] && ulimit -f 2000; exec '$mpi' bake run/part_0.binlines -o full.lbc.h5" \
  >full/out.txt 2>&1 </dev/null
code=$?
check "a failed collective write on rank 1 ends the job with exit 3, not a hang" test "$code" -eq 3
check "it names the rank and the dataset" grep -q "rank 1: full.lbc.h5: dataset /" full/out.txt
# MPI-IO passes no errno up ("file write failed"): the bake looks at the file size limit and
# the free space itself.
check "it names the cause: the file size limit" grep -q "rank 1: full.lbc.h5: dataset /.*file write failed: the file is at the file size limit (ulimit -f) of 1.95 MiB" full/out.txt
check "no cache, temporary or spill file is left" bash -c "! ls -a | grep -E '^full\.lbc\.h5' | grep -v '^full\.lbc\.h5\.lock$'"
# The abort killed rank 0 holding the cache's lock: its file may be left, the lock is not, and
# the next bake into the path takes it and removes it.
check "the cache's lock is not held after the abort; the next bake removes its file" bash -c "
  flock -n full.lbc.h5.lock true && '$bin' bake run/part_0.binlines -o full.lbc.h5 >/dev/null 2>&1 &&
  [ -e full.lbc.h5 ] && [ ! -e full.lbc.h5.lock ]"
# A cache path that is a symbolic link is written through, as the serial bake does.
mkdir linked
ln -s linked/target.lbc.h5 link.lbc.h5
check "np 2 bakes through a symbolic link: the link kept, the file it names a cache" bash -c "
  mpirun -np 2 '$mpi' bake run/part_0.binlines -o link.lbc.h5 > /dev/null 2>&1 &&
  [ -L link.lbc.h5 ] && '$bin' report --json linked/target.lbc.h5 | grep -q '\"ranks\": 2'"

# Rank 0 alone takes the cache's lock: a lock it cannot open (a symbolic link in its place) had
# ended rank 0 with exit 3 and left rank 1 waiting in the bake for ever.
ln -s nowhere stuck.lbc.h5.lock
check "np 2: a lock file rank 0 cannot open stops every rank with exit 3 (rank 1 had waited for ever)" bash -c "
  timeout 60 mpirun -np 2 '$mpi' bake run/part_0.binlines -o stuck.lbc.h5 < /dev/null > stuck.txt 2>&1
  [ \$? -eq 3 ] && grep -q 'rank 0: stuck.lbc.h5: cannot open its lock file' stuck.txt && [ ! -e stuck.lbc.h5 ]"
rm -f stuck.lbc.h5.lock
# A misnamed attribute is the serial bake's usage error (exit 1), found from the header before any
# line is read (it had been exit 4 once the tubes began, through MPI_Abort).
check "np 2: an unknown --attribute is exit 1 naming it, as the serial bake" bash -c "
  timeout 60 mpirun -np 2 '$mpi' bake run/part_0.binlines -o attr.lbc.h5 --attribute nothere < /dev/null > attr.txt 2>&1
  [ \$? -eq 1 ] && grep -q \"rank 0: --attribute: no attribute named 'nothere' in these lines\" attr.txt &&
  ! grep -q MPI_ABORT attr.txt && [ ! -e attr.lbc.h5 ]"

# Each rank's budget is checked as the serial bake checks its own: the least to work in, before
# any line is read (30M had run 30 times as long, over it), and a line longer than a batch (a
# line of 400,000 points had passed 169 MiB under 100M).
check_budget "np 2: a budget under the least a bake works in is refused up front (exit 4)" bash -c "
  timeout 60 mpirun -np 2 '$mpi' bake run/part_0.binlines -o least.lbc.h5 --memory-budget 30M < /dev/null > least.txt 2>&1
  [ \$? -eq 4 ] && grep -q 'is less than the process already holds .* plus 32 MiB to work in' least.txt &&
  [ ! -e least.lbc.h5 ]"
awk 'BEGIN { print "line_id,x,y,z"; for (i = 0; i < 400000; ++i) printf "0,%.6f,%.6f,%.6f\n", cos(i / 4000), sin(i / 4000), i / 400000 }' > long.csv
"$bin" convert long.csv -o long.binlines > /dev/null 2>&1
check_budget "np 2: a line longer than a batch leaves is refused as the serial bake refuses it (exit 4)" bash -c "
  '$bin' bake long.binlines -o long-serial.lbc.h5 --memory-budget 100M 2> long-serial.txt
  [ \$? -eq 4 ] && grep -q 'line 0 has 400000 points; baking it needs about' long-serial.txt &&
  timeout 60 mpirun -np 2 '$mpi' bake long.binlines -o long-mpi.lbc.h5 --memory-budget 100M < /dev/null > long-mpi.txt 2>&1
  [ \$? -eq 4 ] && grep -q 'line 0 has 400000 points; baking it needs about' long-mpi.txt && [ ! -e long-mpi.lbc.h5 ]"

# A rank's stderr is a pipe whatever mpirun's is: rank 0 draws its bars when asked.
check "np 2: mpirun -x LINEBAKE_PROGRESS=always draws rank 0's progress bars, none otherwise" bash -c "
  mpirun -x LINEBAKE_PROGRESS=always -np 2 '$mpi' bake run/part_0.binlines -o bars.lbc.h5 < /dev/null > bars.txt 2>&1 &&
  grep -qa 'reading run/part_0.binlines .*100.0%' bars.txt && [ \$(tr -cd '\\033' < bars.txt | wc -c) -gt 0 ] &&
  rm bars.lbc.h5 && mpirun -np 2 '$mpi' bake run/part_0.binlines -o bars.lbc.h5 < /dev/null > bars.txt 2>&1 &&
  [ \$(tr -cd '\\033\\r' < bars.txt | wc -c) -eq 0 ]"

check "np 2: a command-line error says 'linebake-mpi: error:' and where the options are listed, exit 1" bash -c "
  mpirun -np 2 '$mpi' bake run/part_0.binlines -o grid.lbc.h5 --assets voxels --grid 5000 < /dev/null > grid.txt 2>&1
  [ \$? -eq 1 ] && grep -q '^linebake-mpi: error: --grid: 5000 is outside 1..4096' grid.txt &&
  grep -q '(linebake-mpi bake --help lists the options)' grid.txt && ! grep -q 'Run with --help' grid.txt"

echo "mpi: $passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
