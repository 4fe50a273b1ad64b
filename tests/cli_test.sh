#!/usr/bin/env bash
# CLI tests: every subcommand, exit codes, JSON output, and exact round trips through every
# writable format via `linebake convert`.
set -u
bin="$1"
# shellcheck source=tests/check.sh
source "$(dirname "$0")/check.sh"

# help and version
check "help" "$bin" --help
check "info help" "$bin" info --help
check "convert help" "$bin" convert --help
check "synth help" "$bin" synth --help
check "version" bash -c "'$bin' --version | grep -q '[0-9]\.[0-9]'"
# The build's sources: a commit of this checkout's history (HEAD, or before it where the build
# predates the last commit), ten hex digits and "+modified" for changes to tracked files; or
# "unknown" outside git.
check "version --json: the commit the sources are at" bash -c "rev=\$('$bin' version --json | python3 -c 'import json, sys; print(json.load(sys.stdin)[\"source_revision\"])') && if git -C '$(dirname "$0")' rev-parse HEAD > /dev/null 2>&1; then [[ \"\$rev\" =~ ^[0-9a-f]{10}(\+modified)?\$ ]] && git -C '$(dirname "$0")' merge-base --is-ancestor \"\${rev%+modified}\" HEAD; else [ \"\$rev\" = unknown ]; fi"
check "no subcommand is a usage error" exit_code 1 "$bin"
check "unknown option is a usage error" exit_code 1 "$bin" info --bogus x

# synth + info --json: the done-when of the foundation issue
check "synth" "$bin" synth convection --scale 0.05 -o "$tmp/c.binlines"
check "info json" bash -c "'$bin' info '$tmp/c.binlines' --json > '$tmp/c.json'"
for key in '"lines"' '"points"' '"segments": 495000' '"attributes"' '"bounds"' '"name": "curvature"'; do
  check "info json has $key" grep -q "$key" "$tmp/c.json"
done
check "info text" bash -c "'$bin' info '$tmp/c.binlines' | grep -q 'segments    495000'"
check "info of a synth source" bash -c "'$bin' info 'synth:aneurysm?scale=0.002&seed=5' | grep -q 'segments    4600'"

# The same input, the same bytes: an HDF5 line file written a second later is the same file (no
# object write times in its headers).
check "convert to .h5 twice, a second apart: the same bytes" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/t1.h5' 2>/dev/null && sleep 1.1 && '$bin' convert '$tmp/c.binlines' -o '$tmp/t2.h5' 2>/dev/null && cmp '$tmp/t1.h5' '$tmp/t2.h5'"
# convert streams into .binlines in bounded memory; a format written whole (or read whole) is held
# within --memory-budget, refused with the figures before anything is written.
for cmd in "convert '$tmp/c.binlines' -o '$tmp/z.binlines'" "bake '$tmp/c.binlines' -o '$tmp/z.lbc.h5'" "bench voxels '$tmp/c.binlines'" "synth convection --scale 0.01 -o '$tmp/z.vtp'"; do
  check "--memory-budget 0 is a usage error (exit 1): ${cmd%% *}" bash -c "'$bin' $cmd --memory-budget 0 2> '$tmp/z.err'; [ \$? -eq 1 ] && grep -q 'a memory budget of 0 bytes leaves no room for any work' '$tmp/z.err' && [ ! -e '$tmp/z.binlines' ] && [ ! -e '$tmp/z.lbc.h5' ] && [ ! -e '$tmp/z.vtp' ]"
done
check "convert to .binlines under a 40M budget streams: the same bytes" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/stream.binlines' --memory-budget 40M 2>/dev/null && cmp '$tmp/c.binlines' '$tmp/stream.binlines'"
check "convert to .vtp past a 40M budget is refused (exit 4), nothing written" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/big.vtp' --memory-budget 40M 2> '$tmp/big.err'; [ \$? -eq 4 ] && grep -q 'vtp is written whole: the first .* points take .* with writing them, more than the memory budget of 40.00 MiB leaves' '$tmp/big.err' && [ ! -e '$tmp/big.vtp' ]"
# every writable format and back gives the same bytes
for ext in obj vtk h5 csv vtp binlines; do
  check "convert to $ext" "$bin" convert "$tmp/c.binlines" -o "$tmp/c2.$ext"
  check "convert back from $ext" "$bin" convert "$tmp/c2.$ext" -o "$tmp/back-$ext.binlines"
  check "$ext round trip is exact" cmp "$tmp/c.binlines" "$tmp/back-$ext.binlines"
done
# A format read whole is refused where the reader's next allocation would pass the budget (its
# 495,000 segments are 7.6 MiB as lines; reading takes 2 to 3 times that), before it is made.
for place in "obj:at line " "vtk:at POINTS (500153 points)" "vtp:at Piece (500153 points, 5153 lines)"; do
  ext=${place%%:*}
  check "convert from $ext past a 24M budget is refused while reading (exit 4, '${place#*:}'), nothing written" bash -c "'$bin' convert '$tmp/c2.$ext' -o '$tmp/rb-$ext.binlines' --memory-budget 24M 2> '$tmp/rb.err'; [ \$? -eq 4 ] && grep -qF '$tmp/c2.$ext: $ext is read whole: ${place#*:}' '$tmp/rb.err' && [ ! -e '$tmp/rb-$ext.binlines' ]"
done
check "a budget used up before reading still bounds the reader (refused at POINTS, exit 4)" bash -c "'$bin' convert '$tmp/c2.vtk' -o '$tmp/rb8.binlines' --memory-budget 8M 2> '$tmp/rb.err'; [ \$? -eq 4 ] && grep -q 'vtk is read whole: at POINTS' '$tmp/rb.err' && [ ! -e '$tmp/rb8.binlines' ]"
check "an ASCII VTP is checked before its XML is copied (exit 4)" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/ascii.vtp' --vtp-encoding ascii 2>/dev/null && '$bin' convert '$tmp/ascii.vtp' -o '$tmp/rba.binlines' --memory-budget 24M 2> '$tmp/rb.err'; [ \$? -eq 4 ] && grep -q 'vtp is read whole: at its XML' '$tmp/rb.err'"
check "an OBJ line of a million indices is checked before it is split (exit 4)" bash -c "python3 -c \"print('v 0 0 0'); print('v 1 1 1'); print('l ' + '1 2 ' * 500000)\" > '$tmp/long.obj' && '$bin' convert '$tmp/long.obj' -o '$tmp/rbl.binlines' --memory-budget 24M 2> '$tmp/rb.err'; [ \$? -eq 4 ] && grep -q 'obj is read whole: at line 3 ' '$tmp/rb.err'"
check "a VTP of a million small elements is checked for its parser's nodes before it parses (exit 4)" bash -c "python3 -c \"print('<?xml version=\\\"1.0\\\"?><VTKFile type=\\\"PolyData\\\"><PolyData>' + '<a/>' * 1000000 + '</PolyData></VTKFile>')\" > '$tmp/nodes.vtp' && '$bin' convert '$tmp/nodes.vtp' -o '$tmp/nodes.binlines' --memory-budget 40M 2> '$tmp/rb.err'; [ \$? -eq 4 ] && grep -q 'vtp is read whole: at its XML' '$tmp/rb.err'"
check "an OBJ line too long for the budget is refused as its buffer grows, naming its line (3)" bash -c "python3 -c \"print('v 0 0 0'); print('v 1 1 1'); print('l ' + '1 2 ' * 10000000)\" > '$tmp/longer.obj' && '$bin' convert '$tmp/longer.obj' -o '$tmp/rbl2.binlines' --memory-budget 100M 2> '$tmp/rb.err'; [ \$? -eq 4 ] && grep -q 'obj is read whole: at line 3 ' '$tmp/rb.err'"
# Counts a file cannot hold are the file's error (exit 2), whatever the budget.
printf '# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1 1\nLINES 1000000000000 3000000000000\n' > "$tmp/huge_cells.vtk"
check "VTK cell counts past the file are exit 2, not a budget refusal" bash -c "'$bin' convert '$tmp/huge_cells.vtk' -o '$tmp/hc.binlines' 2> '$tmp/rb.err'; [ \$? -eq 2 ] && grep -q 'cannot be in the' '$tmp/rb.err'"
printf '<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian"><PolyData><Piece NumberOfPoints="2" NumberOfLines="1"><Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 1 1</DataArray></Points><Lines><DataArray type="Int64" Name="connectivity" format="ascii">0 1</DataArray><DataArray type="Int64" Name="offsets" format="ascii">-1</DataArray></Lines></Piece></PolyData></VTKFile>\n' > "$tmp/negative.vtp"
printf '<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian"><PolyData><Piece NumberOfPoints="2" NumberOfLines="1"><Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 1 1</DataArray></Points><Lines><DataArray type="Int64" Name="offsets" format="ascii">1000000000000000</DataArray></Lines></Piece></PolyData></VTKFile>\n' > "$tmp/noconn.vtp"
check "a VTP with a huge last offset and no connectivity is exit 2, not a budget refusal" bash -c "'$bin' convert '$tmp/noconn.vtp' -o '$tmp/nc.binlines' 2> '$tmp/rb.err'; [ \$? -eq 2 ] && grep -q 'missing connectivity array' '$tmp/rb.err'"
check "a VTP whose last offset is negative is exit 2, not a budget refusal" bash -c "'$bin' convert '$tmp/negative.vtp' -o '$tmp/neg.binlines' 2> '$tmp/rb.err'; [ \$? -eq 2 ] && grep -q 'the last offset -1 is negative' '$tmp/rb.err'"
# info reads a streamable file a batch at a time and a VTP whole: the same statistics and
# validation (an independent path: compute_stats over the whole set).
info_body() { "$bin" info "$1" --json | python3 -c "import json, sys; d = json.load(sys.stdin); [d.pop(k) for k in ('source', 'format', 'metadata')]; print(json.dumps(d, sort_keys=True))"; }
check "info streamed (binlines, h5) and whole (vtp): the same figures" bash -c "$(declare -f info_body); bin='$bin'; a=\$(info_body '$tmp/c.binlines') && [ \"\$a\" = \"\$(info_body '$tmp/c2.vtp')\" ] && [ \"\$a\" = \"\$(info_body '$tmp/c2.h5')\" ]"
check "convert X X is refused, X unchanged" bash -c "cp '$tmp/c.binlines' '$tmp/same.binlines'; '$bin' convert '$tmp/same.binlines' -o '$tmp/same.binlines' 2> '$tmp/same.err'; [ \$? -eq 3 ] && grep -q 'never replaces its input' '$tmp/same.err' && cmp '$tmp/c.binlines' '$tmp/same.binlines'"
check "vtk ascii round trip" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/a.vtk' --ascii && '$bin' convert '$tmp/a.vtk' -o '$tmp/a.binlines' && cmp '$tmp/c.binlines' '$tmp/a.binlines'"
check "format override" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/c.data' --to hdf5 && '$bin' info '$tmp/c.data' --from hdf5 | grep -q 495000"
check "derive" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/d.h5' --derive segment_length,line_length && '$bin' info '$tmp/d.h5' | grep -q 'line attr.  line_length'"

# bad input: clear error, non-zero exit, no output left behind
printf 'v 0 0 0\nv 1 1 1\nl 1 7\n' > "$tmp/bad.obj"
check "bad input exits 2" exit_code 2 "$bin" convert "$tmp/bad.obj" -o "$tmp/out.vtk"
check "error names file and line" bash -c "'$bin' convert '$tmp/bad.obj' -o '$tmp/out.vtk' 2>&1 | grep -q 'bad.obj: line 3'"
check "no output after bad input" test ! -e "$tmp/out.vtk"
check "no temporary files left" bash -c "! ls '$tmp' | grep -q tmp-"
printf 'v 0 0 0\nv 0 0 0\nv 1 1 1\nl 1 2 3\n' > "$tmp/rep.obj"
check "reject policy exits 2" exit_code 2 "$bin" convert "$tmp/rep.obj" -o "$tmp/rep.csv" --on-invalid reject
check "repair policy reports" bash -c "'$bin' convert '$tmp/rep.obj' -o '$tmp/rep.csv' 2>&1 | grep -q '1 repeated consecutive points'"
check "missing input exits 2" exit_code 2 "$bin" info "$tmp/none.obj"
check "unwritable output exits 3" exit_code 3 "$bin" convert "$tmp/c.binlines" -o "$tmp/no/such/dir/x.vtk"
check "unknown output format (a bad output path): exit 3" exit_code 3 "$bin" convert "$tmp/c.binlines" -o "$tmp/x.unknown"
check "convert IN OUT (deprecated): works, warns" bash -c "'$bin' convert '$tmp/c.binlines' '$tmp/dep.vtk' 2> '$tmp/dep.err' && grep -q 'linebake: warning: convert IN OUT is deprecated; use convert IN -o OUT' '$tmp/dep.err' && '$bin' convert '$tmp/dep.vtk' -o '$tmp/dep.binlines' 2>/dev/null && cmp '$tmp/c.binlines' '$tmp/dep.binlines'"
check "info --memory-budget: a file read whole past it is refused (exit 4); unlimited reads it" bash -c "'$bin' info '$tmp/dep.vtk' --memory-budget 1M > /dev/null 2> '$tmp/ib.err'; [ \$? -eq 4 ] && grep -q 'dep.vtk.*memory budget' '$tmp/ib.err' && '$bin' info '$tmp/dep.vtk' --memory-budget unlimited --json | grep -q '\"segments\"'"
check "unknown synth set is a usage error" exit_code 1 "$bin" synth galaxy -o "$tmp/g.obj"

# bake / report / export / bench
check "bake" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' > '$tmp/bake.txt'"
check "bake prints the report" grep -q "LS (segments)   495,000" "$tmp/bake.txt"
check "second bake reuses" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' 2>&1 >/dev/null | grep -q 'tubes: up to date, reused'"
check "render --geometry (deprecated): rewritten to --embree-geometry, warns" bash -c "'$bin' render '$tmp/c.lbc.h5' --geometry bezier --size 24x16 -o '$tmp/dep.png' --stats '$tmp/dep.json' 2> '$tmp/dep.err' && grep -q 'render --geometry is deprecated; use --embree-geometry' '$tmp/dep.err' && grep -q '\"geometry\": \"bezier\"' '$tmp/dep.json'"
check "a cache under any name is a line source" bash -c "cp '$tmp/c.lbc.h5' '$tmp/cache.data' && '$bin' info '$tmp/cache.data' --json | grep -q '\"segments\": 495000' && '$bin' convert '$tmp/cache.data' -o '$tmp/fromcache.binlines' 2>/dev/null && cmp '$tmp/c.binlines' '$tmp/fromcache.binlines'"
check "--force rebuilds" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' --force 2>&1 >/dev/null | grep -q 'tubes: built'"
# An output never replaces an input of its command, and two outputs are never one file: refused
# before any work (exit 3), the files as they were.
refused_keeps() {  # name, the file that must stay unchanged, the command...
  local name="$1" keep="$2"
  shift 2
  cp "$keep" "$tmp/kept.copy"
  check "$name" bash -c "\"\$@\" 2> '$tmp/refused.err'; [ \$? -eq 3 ] && cmp '$keep' '$tmp/kept.copy' && grep -Eq 'never replaces its input|each output needs a file of its own' '$tmp/refused.err'" _ "$@"
}
refused_keeps "render --stats naming the cache is refused" "$tmp/c.lbc.h5" \
  "$bin" render "$tmp/c.lbc.h5" --technique embree --size 24x16 -o "$tmp/r.png" --stats "$tmp/c.lbc.h5"
refused_keeps "depth-complexity --stats naming the cache is refused" "$tmp/c.lbc.h5" \
  "$bin" depth-complexity "$tmp/c.lbc.h5" --size 24x16 -o "$tmp/d.png" --stats "$tmp/c.lbc.h5"
check "render: an image and its depth complexity in one file (named two ways) are refused, nothing written" bash -c "cd '$tmp' && '$(realpath "$bin")' render c.lbc.h5 --technique embree --size 24x16 -o both.png --depth-complexity ../\$(basename '$tmp')/./both.png 2> both.err; [ \$? -eq 3 ] && grep -q 'is also the output' both.err && [ ! -e both.png ]"
check "render --frames all: a numbered frame naming the cache is refused" bash -c "cp '$tmp/c.lbc.h5' '$tmp/f_001.png'; '$bin' render '$tmp/f_001.png' --technique embree --size 24x16 --frames all --frame-count 2 -o '$tmp/f.png' 2> '$tmp/f.err'; [ \$? -eq 3 ] && grep -q 'never replaces its input' '$tmp/f.err' && cmp '$tmp/c.lbc.h5' '$tmp/f_001.png'"
cp "$tmp/c.lbc.h5" "$tmp/m.bin"
refused_keeps "export: a .gltf whose .bin would be the cache is refused" "$tmp/m.bin" \
  "$bin" export "$tmp/m.bin" -o "$tmp/m.gltf"
cp "$tmp/c.binlines" "$tmp/victim.binlines"
refused_keeps "bench bake with -o naming its input is refused, the input kept" "$tmp/victim.binlines" \
  "$bin" bench bake "$tmp/victim.binlines" -o "$tmp/victim.binlines"
# The tube mesh (one chunk of 71.19 MiB: 1,500,459 vertices of 26 bytes, 2,970,000 triangles of
# 12) needs 1.1 times its chunk and 24 MiB: 102.31 MiB.
check "export: a glTF built past the budget is refused before reading (exit 4), nothing written" bash -c "'$bin' export '$tmp/c.lbc.h5' -o '$tmp/eb.glb' --memory-budget 100M 2> '$tmp/eb.err'; [ \$? -eq 4 ] && grep -q \"building the tube mesh's glTF takes about 102.31 MiB\" '$tmp/eb.err' && [ ! -e '$tmp/eb.glb' ]"
check "export: a mesh in 8 MB chunks is written a chunk at a time within 60M, the same bytes as unlimited, Draco's spill gone" bash -c "
  bin='$(realpath "$bin")' && mkdir -p '$tmp/ec' && cd '$tmp/ec' && \"\$bin\" bake ../c.binlines -o ec.lbc.h5 --assets tubes --chunk-bytes 8000000 2>/dev/null &&
  \"\$bin\" export ec.lbc.h5 -o a.glb --memory-budget 60M 2>/dev/null && \"\$bin\" export ec.lbc.h5 -o b.glb --memory-budget unlimited 2>/dev/null && cmp a.glb b.glb &&
  \"\$bin\" export ec.lbc.h5 -o d.gltf --draco --memory-budget unlimited 2>/dev/null && [ \"\$(ls | tr '\\n' ' ')\" = 'a.glb b.glb d.bin d.gltf ec.lbc.h5 ' ]"
check "synth to a format written whole past the budget is refused (exit 4), nothing written" bash -c "'$bin' synth convection --scale 0.1 -o '$tmp/sb.vtp' --memory-budget 40M 2> '$tmp/sb.err'; [ \$? -eq 4 ] && grep -q 'vtp is written whole: the first .* points take .*, more than the memory budget of 40.00 MiB leaves' '$tmp/sb.err' && [ ! -e '$tmp/sb.vtp' ]"
# An output that is not a regular file is not renamed over (as root, /dev/null would have become
# a file); a symbolic link is written through and stays a link.
check "convert onto a FIFO is refused (exit 3), the FIFO kept" bash -c "mkfifo '$tmp/fifo.binlines' && '$bin' convert '$tmp/c.binlines' -o '$tmp/fifo.binlines' 2> '$tmp/fifo.err'; [ \$? -eq 3 ] && grep -q 'is not a regular file' '$tmp/fifo.err' && [ -p '$tmp/fifo.binlines' ]"
check "convert onto a symbolic link writes the file it names, the link kept" bash -c "mkdir -p '$tmp/real' && ln -sf '$tmp/real/target.binlines' '$tmp/link.binlines' && '$bin' convert '$tmp/c.binlines' -o '$tmp/link.binlines' 2>/dev/null && [ -L '$tmp/link.binlines' ] && cmp '$tmp/c.binlines' '$tmp/real/target.binlines'"
check "compare: an infinity in a PFM is refused naming the pixel (exit 2), not clamped and measured" bash -c "/usr/bin/python3 -c \"import struct, sys; v = [0.25] * 48; v[3 * (1 * 4 + 2)] = float('inf'); open(sys.argv[1], 'wb').write(b'PF\\n4 4\\n-1.0\\n' + struct.pack('<48f', *v))\" '$tmp/inf.pfm' && '$bin' compare '$tmp/inf.pfm' '$tmp/inf.pfm' 2> '$tmp/inf.err'; [ \$? -eq 2 ] && grep -q 'inf.pfm: pixel (2, [12]): not a finite value' '$tmp/inf.err'"
check "export to a .gltf through a symbolic link: the .bin lands beside the file it names" bash -c "mkdir -p '$tmp/gl' && ln -sf '$tmp/gl/model.gltf' '$tmp/out.gltf' && '$bin' export '$tmp/c.lbc.h5' -o '$tmp/out.gltf' 2>'$tmp/gl.err' && grep -q \"wrote $tmp/gl/model.bin (\" '$tmp/gl.err' && [ -L '$tmp/out.gltf' ] && [ -s '$tmp/gl/model.bin' ] && grep -q '\"uri\": \"model.bin\"' '$tmp/gl/model.gltf'"
check "a symbolic link into a missing directory is refused before any work (exit 3), naming both" bash -c "ln -sf '$tmp/nowhere/out.vdb' '$tmp/dangling.vdb' && '$bin' export '$tmp/c.lbc.h5' -o '$tmp/dangling.vdb' 2> '$tmp/dl.err'; [ \$? -eq 3 ] && grep -qF \"dangling.vdb: the directory $tmp/nowhere does not exist (where the link leads: $tmp/nowhere/out.vdb)\" '$tmp/dl.err'"
check "a loop of symbolic links as the output is refused (exit 3), the links kept" bash -c "ln -sf '$tmp/loop-b.binlines' '$tmp/loop-a.binlines' && ln -sf '$tmp/loop-a.binlines' '$tmp/loop-b.binlines' && '$bin' convert '$tmp/c.binlines' -o '$tmp/loop-a.binlines' 2> '$tmp/loop.err'; [ \$? -eq 3 ] && grep -q 'loop-a.binlines: is a loop of symbolic links' '$tmp/loop.err' && [ -L '$tmp/loop-a.binlines' ] && [ -L '$tmp/loop-b.binlines' ]"
check "an output name of 255 bytes is written, baked and rendered (its temporary, spill and lock names had passed the limit once the work was done)" bash -c "n=\$(printf 'n%.0s' \$(seq 247)) && mkdir -p '$tmp/long' && cd '$tmp/long' && '$bin' convert 'synth:aneurysm?scale=0.01' -o \$n.vtp && '$bin' bake \$n.vtp -o \$n.lbc.h5 && '$bin' render \$n.lbc.h5 --size 16x12 -o \$n.png && [ \$(ls -A | wc -l) -eq 3 ] && [ -s \$n.png ]"
check "standard output that cannot be written fails the command (exit 3)" bash -c "'$bin' info '$tmp/c.binlines' --json > /dev/full 2> '$tmp/full.err'; [ \$? -eq 3 ] && grep -q 'standard output: a write failed: No space left on device' '$tmp/full.err'"
check "help and --version to a full standard output fail too (exit 3)" bash -c "for a in --help 'render --help' --version 'help bake'; do '$bin' \$a > /dev/full 2> /dev/null; [ \$? -eq 3 ] || exit 1; done"
check "bench bake to a full standard output names no cache it removed (it had named the cache as written whole)" bash -c "'$bin' bench bake 'synth:aneurysm?scale=0.005' -o '$tmp/bbfull.lbc.h5' --repeat 1 --json > /dev/full 2> '$tmp/bbfull.err'; [ \$? -eq 3 ] && grep -q 'standard output: a write failed' '$tmp/bbfull.err' && ! grep -q 'written whole before it' '$tmp/bbfull.err'"
check "an output written whole before standard output failed is named, and left whole" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/full.vtp' > /dev/full 2> '$tmp/full2.err'; [ \$? -eq 0 ] && '$bin' render '$tmp/c.lbc.h5' --size 8x6 -o '$tmp/full.png' --json > /dev/full 2> '$tmp/full3.err'; [ \$? -eq 3 ] && grep -q 'standard output: a write failed' '$tmp/full3.err' && grep -qF '(written whole before it: $tmp/full.png)' '$tmp/full3.err' && [ -s '$tmp/full.png' ]"
# The 71 MiB tube mesh (one chunk) does not fit what these budgets leave: refused before it is
# read, with the figures, not left to grow (depth-complexity loaded it unchecked; ll read the
# whole chunk before the budget saw it).
check "depth-complexity: a mesh past the budget is refused before it is read (exit 4)" bash -c "'$bin' depth-complexity '$tmp/c.lbc.h5' --size 24x16 -o '$tmp/dcb.png' --memory-budget 50M 2> '$tmp/dcb.err'; [ \$? -eq 4 ] && grep -q \"tube mesh's buffers take 71.19 MiB\" '$tmp/dcb.err' && [ ! -e '$tmp/dcb.png' ]"
check "ll: a tube chunk past what the budget leaves is refused before it is read (exit 4)" bash -c "'$bin' render '$tmp/c.lbc.h5' --technique ll --size 24x16 -o '$tmp/llb.png' --memory-budget 120M 2> '$tmp/llb.err'; [ \$? -eq 4 ] && grep -q \"chunk 0 (bake --chunk-bytes sets a chunk's size) take 71.19 MiB\" '$tmp/llb.err'"
check "new sides rebuild tubes only" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' --tube-sides 4 2>&1 >/dev/null | tr '\n' ' ' | grep -q 'lines: up to date, reused linebake: tubes: built'"
check "--compression applies to /lines as well" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' --tube-sides 4 --compression deflate 2>&1 >/dev/null | tr '\n' ' ' | grep -q 'lines: built linebake: tubes: built' && h5dump -p -H -d /lines/points '$tmp/c.lbc.h5' | grep -q DEFLATE"
check "report markdown" bash -c "'$bin' report '$tmp/c.lbc.h5' --markdown | grep -q '^| c | 5,153 | 495,000 |'"
check "report json" bash -c "'$bin' report '$tmp/c.lbc.h5' --json | grep -q '\"triangles\": 3960000'"
check "report names h5dump-readable layout" bash -c "h5dump -H '$tmp/c.lbc.h5' | grep -q 'DATASET \"positions\"'"
check "export glb" "$bin" export "$tmp/c.lbc.h5" --glb "$tmp/c.glb" --lines
check "export --lines: the lines carry the tubes' attribute and range, with or without the tubes" bash -c "'$bin' convert 'synth:aneurysm?scale=0.01' -o '$tmp/attr.h5' --derive curvature >/dev/null 2>&1 && '$bin' bake '$tmp/attr.h5' -o '$tmp/attr.lbc.h5' --attribute curvature >/dev/null 2>&1 && '$bin' export '$tmp/attr.lbc.h5' -o '$tmp/attr.glb' --lines >/dev/null 2>&1 && '$bin' export '$tmp/attr.lbc.h5' -o '$tmp/attr-lines.glb' --lines --no-tubes >/dev/null 2>&1 && /usr/bin/python3 -c \"
import json, struct
def meshes(path):
    data = open(path, 'rb').read()
    return {m['name']: m['extras'] for m in json.loads(data[20:20 + struct.unpack('<I', data[12:16])[0]])['meshes']}
both, alone = meshes('$tmp/attr.glb'), meshes('$tmp/attr-lines.glb')
assert both['tubes']['linebake_attribute'] == 'curvature', both
assert both['lines'] == {k: both['tubes'][k] for k in both['lines']}, both
assert alone['lines'] == both['lines'], (alone, both)
\""
check "convert --ascii to .vtk says when NaN or infinities are written (VTK's legacy reader cannot read them); binary says nothing" bash -c "'$bin' convert 'synth:aneurysm?scale=0.001' -o '$tmp/nanv.csv' 2>/dev/null && sed '3s/,[^,]*\$/,nan/; 5s/,[^,]*\$/,-inf/' '$tmp/nanv.csv' > '$tmp/nanv2.csv' && '$bin' convert '$tmp/nanv2.csv' -o '$tmp/nanv.vtk' --ascii 2> '$tmp/nanv.err' && grep -qF \"$tmp/nanv.vtk: 2 NaN or infinite value(s) are written as nan or inf in ASCII\" '$tmp/nanv.err' && '$bin' convert '$tmp/nanv2.csv' -o '$tmp/nanv-b.vtk' 2> '$tmp/nanv-b.err' && ! grep -q 'NaN or infinite' '$tmp/nanv-b.err'"
check "export draco" "$bin" export "$tmp/c.lbc.h5" --glb "$tmp/cd.glb" --draco --draco-bits 12
check "draco is smaller" bash -c "[ \$(stat -c %s '$tmp/cd.glb') -lt \$(stat -c %s '$tmp/c.glb') ]"
check_budget "export --draco in pieces of one vertex (one a line) under a budget just above its estimate: the peak within it" /usr/bin/python3 -c "
import re, subprocess, resource
run = lambda budget: subprocess.run(['$bin', 'export', '$tmp/c.lbc.h5', '--glb', '$tmp/p1.glb', '--draco', '--draco-piece-vertices', '1', '--memory-budget', budget], capture_output=True, text=True)
refused = run('30M')
assert refused.returncode == 4, refused.stderr
m = re.search(r'takes about ([0-9.]+) MiB .* leaves \\(([0-9.]+) MiB\\)', refused.stderr)
estimate, held = float(m.group(1)), 30 - float(m.group(2))
budget = int(estimate + held) + 2
done = run(f'{budget}M')
assert done.returncode == 0, done.stderr
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
assert peak <= budget, (peak, budget)"
check "--draco-piece-vertices is read only with --draco (usage error)" exit_code 1 "$bin" export "$tmp/c.lbc.h5" --glb "$tmp/np.glb" --draco-piece-vertices 1000
check "export draco in pieces of 20,000 vertices: more primitives than chunks, a smaller peak than one piece" /usr/bin/python3 -c "
import json, struct, subprocess, resource
def run(out, *extra):
    subprocess.run(['$bin', 'export', '$tmp/c.lbc.h5', '--glb', out, '--draco', '--memory-budget', 'unlimited', *extra], check=True, capture_output=True)
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
def primitives(path):
    data = open(path, 'rb').read()
    n = struct.unpack_from('<I', data, 12)[0]
    return len(json.loads(data[20:20 + n])['meshes'][0]['primitives'])
# the children's peak so far: the pieces' run first, so a larger one after is the whole chunk's
pieces = run('$tmp/dp.glb', '--draco-piece-vertices', '20000')
whole = run('$tmp/d1.glb', '--draco-piece-vertices', '4294967296')
assert primitives('$tmp/dp.glb') > primitives('$tmp/d1.glb'), (primitives('$tmp/dp.glb'), primitives('$tmp/d1.glb'))
assert pieces < whole, (pieces, whole)"
check "bake of a bad input exits 2" exit_code 2 "$bin" bake "$tmp/bad.obj" -o "$tmp/bad.lbc.h5" --on-invalid reject
check "no cache after bad input" test ! -e "$tmp/bad.lbc.h5"
head -c 3000 "$tmp/c.lbc.h5" > "$tmp/trunc.lbc.h5"
check "truncated cache exits 2" exit_code 2 "$bin" export "$tmp/trunc.lbc.h5" --glb "$tmp/t.glb"
check "truncated cache error names the file" bash -c "'$bin' report '$tmp/trunc.lbc.h5' 2>&1 | grep -q 'trunc.lbc.h5'"
check "no glb after a bad cache" test ! -e "$tmp/t.glb"
check "report of a non-cache exits 2" exit_code 2 "$bin" report "$tmp/c2.h5"
check "unknown asset" exit_code 1 "$bin" bake "$tmp/c.binlines" -o "$tmp/u.lbc.h5" --assets voxels2
check "bake voxels next to tubes" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' --tube-sides 4 --compression deflate --assets tubes,voxels --grid 96 --quantization 16 2>&1 >/dev/null | tr '\\n' ' ' | grep -q 'tubes: up to date, reused linebake: voxels: built'"
check "report has the VRC column" bash -c "'$bin' report '$tmp/c.lbc.h5' --markdown | grep -q '96x6x96 Q16'"
check "voxels kept when only tubes are asked for" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/c.lbc.h5' --tube-sides 5 --compression deflate >/dev/null 2>&1 && '$bin' report '$tmp/c.lbc.h5' --json | grep -q '\"quantization\": 16'"
check "export vdb" "$bin" export "$tmp/c.lbc.h5" --vdb "$tmp/c.vdb"
check "vdb starts with the OpenVDB magic" bash -c "[ \"\$(head -c 4 '$tmp/c.vdb' | od -An -tx1 | tr -d ' ')\" = '20424456' ]"
check "export takes upper-case extensions, as convert and render do (.GLB had been refused)" bash -c "'$bin' export '$tmp/c.lbc.h5' -o '$tmp/UP.GLB' -o '$tmp/UP.VDB' >/dev/null 2>&1 && '$bin' export '$tmp/c.lbc.h5' -o '$tmp/UP.GLTF' >/dev/null 2>&1 && [ \"\$(head -c 4 '$tmp/UP.GLB')\" = glTF ] && head -c 1 '$tmp/UP.GLTF' | grep -q '{' && [ -s '$tmp/UP.bin' ] && [ -s '$tmp/UP.VDB' ]"
check "tubes-only bake" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/t.lbc.h5' > /dev/null"
# A VDB is built from the cached grid read a piece at a time, held to the budget by its grids'
# estimate (formats/vdb.hpp): refused before reading past it, the same bytes within it.
check "export vdb past its estimate is refused before reading (exit 4), nothing written" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/v.lbc.h5' --assets voxels --grid 256 > /dev/null 2>&1 && '$bin' export '$tmp/v.lbc.h5' -o '$tmp/v40.vdb' --memory-budget 40M 2> '$tmp/v40.err'; [ \$? -eq 4 ] && grep -q \"building the voxel grid's VDB takes about 66.69 MiB in memory, more than the memory budget of 40.00 MiB leaves\" '$tmp/v40.err' && [ ! -e '$tmp/v40.vdb' ]"
check_budget "export vdb within 130M: the bytes of the unlimited export, the peak within it" /usr/bin/python3 -c "
import subprocess, resource
run = lambda out, budget: subprocess.run(['$bin', 'export', '$tmp/v.lbc.h5', '-o', out, '--memory-budget', budget], check=True, capture_output=True)
run('$tmp/v130.vdb', '130M')
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
run('$tmp/vu.vdb', 'unlimited')
assert open('$tmp/v130.vdb', 'rb').read() == open('$tmp/vu.vdb', 'rb').read()
assert 0 < peak <= 130 << 20, peak"
check "export vdb without voxels exits 2" exit_code 2 "$bin" export "$tmp/t.lbc.h5" --vdb "$tmp/none.vdb"
check "export with no target is an error" exit_code 1 "$bin" export "$tmp/c.lbc.h5"
check "bad grid is a usage error" exit_code 1 "$bin" bake "$tmp/c.binlines" -o "$tmp/g.lbc.h5" --assets voxels --grid 12x3
check "bench tubes" bash -c "'$bin' bench tubes --input '$tmp/c.binlines' --repeat 1 --json | grep -q '\"segments\": 495000'"
check "bench voxels" bash -c "'$bin' bench voxels --input '$tmp/c.binlines' --grid 64 --repeat 1 --json | grep -q '\"resolution\": \\['"

# Embree, render, compare
check "bake embree next to tubes" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/t.lbc.h5' --assets tubes,embree 2>&1 >/dev/null | grep -q 'embree: built'"
check "report has the OSP column" bash -c "'$bin' report '$tmp/t.lbc.h5' --markdown | grep -q 'embree (OSP)'"
check "render embree" "$bin" render "$tmp/t.lbc.h5" --tf semi --frame 3 --frame-count 8 --size 96x64 -o "$tmp/e.png" --stats "$tmp/e.json" --depth-complexity "$tmp/dc.png"
check "render stats json" bash -c "grep -q '\"back_hits_rejected\"' '$tmp/e.json' && grep -q '\"bvh_bytes\"' '$tmp/e.json'"
check "render reference pfm" "$bin" render "$tmp/t.lbc.h5" --technique reference --tf semi --frame 3 --frame-count 8 --size 96x64 -o "$tmp/r.pfm"
check "compare pfm against png of one render" bash -c "'$bin' compare '$tmp/e.png' '$tmp/e.png' | grep -q '60.0000 dB'"
check "compare embree to reference" bash -c "'$bin' compare '$tmp/e.png' '$tmp/r.pfm' --json --error-image '$tmp/err.png' | grep -q '\"ssim\"' && test -s '$tmp/err.png'"
refused_keeps "compare --error-image naming a compared image is refused" "$tmp/e.png" \
  "$bin" compare "$tmp/e.png" "$tmp/r.pfm" --error-image "$tmp/e.png"
check "render all frames" bash -c "'$bin' render '$tmp/t.lbc.h5' --frames all --frame-count 3 --size 32x24 -o '$tmp/f.png' 2>/dev/null && test -s '$tmp/f_000.png' && test -s '$tmp/f_002.png'"
check "tiles: the key sort's two paths give the same bytes, --stats says which ran, auto takes shared memory on lavapipe" bash -c "
set -e
for sort in auto subgroups shared; do
  '$bin' render '$tmp/t.lbc.h5' --technique tiles --tiles-sort \$sort --tf semi --frame 3 --frame-count 8 --size 96x64 -o '$tmp/ts_'\$sort.pfm --stats '$tmp/ts_'\$sort.json 2>/dev/null
done
cmp '$tmp/ts_subgroups.pfm' '$tmp/ts_shared.pfm'
cmp '$tmp/ts_auto.pfm' '$tmp/ts_shared.pfm'
python3 -c \"
import json
a, g, s = (json.load(open('$tmp/ts_' + n + '.json')) for n in ('auto', 'subgroups', 'shared'))
assert g['sort_subgroup_size'] > 0 and s['sort_subgroup_size'] == 0, (g, s)
assert 'llvmpipe' not in a['device'] or a['sort_subgroup_size'] == 0, a
assert a['frames'][0]['keys'] == s['frames'][0]['keys'] > 0, (a, s)
\"
"
check "--tiles-sort is auto, subgroups or shared" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique tiles --tiles-sort warp --size 32x24 -o "$tmp/x.png"
check "tiles: strips give the bytes of whole tiles (the frame of the sort check), four workgroups a tile" bash -c "
set -e
for strips in all crowded; do
  '$bin' render '$tmp/t.lbc.h5' --technique tiles --tiles-strips \$strips --tf semi --frame 3 --frame-count 8 --size 96x64 -o '$tmp/tstrips_'\$strips.pfm --stats '$tmp/tstrips_'\$strips.json 2>/dev/null
  cmp '$tmp/ts_auto.pfm' '$tmp/tstrips_'\$strips.pfm
done
python3 -c \"
import json
whole, every, crowded = (json.load(open(f))['frames'][0] for f in ('$tmp/ts_auto.json', '$tmp/tstrips_all.json', '$tmp/tstrips_crowded.json'))
# 96x64: 24 tiles, fewer than 512, so crowded takes them all in strips too.
assert whole['composite_workgroups'] >= 24 and every['composite_workgroups'] == 4 * whole['composite_workgroups'] == crowded['composite_workgroups'], (whole, every, crowded)
\"
"
check "--tiles-strips is none, crowded or all" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique tiles --tiles-strips some --size 32x24 -o "$tmp/x.png"
check "voxels-only bake" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/v.lbc.h5' --assets voxels --grid 32 > /dev/null 2>&1"
check "reference without tubes is an error" exit_code 2 "$bin" render "$tmp/v.lbc.h5" --technique reference --size 32x24 -o "$tmp/x.png"
check "curves render without tubes" "$bin" render "$tmp/v.lbc.h5" --size 32x24 -o "$tmp/v.png"
printf '{"keyframes": [{"eye": [0, 0], "target": [0, 0, 0]}]}' > "$tmp/bad_keys.json"
check "bad keyframes exit 2" exit_code 2 "$bin" render "$tmp/t.lbc.h5" --flight "$tmp/bad_keys.json" --size 32x24 -o "$tmp/x.png"
check "info: an attribute with no finite value has no range (null in JSON, said in text; it had read as [0, 0])" bash -c "printf 'line_id,x,y,z,a\\n0,0,0,0,nan\\n0,1,0,0,nan\\n' > '$tmp/allnan.csv' && '$bin' info '$tmp/allnan.csv' | grep -q 'attribute   a no finite value 2 non-finite' && '$bin' info '$tmp/allnan.csv' --json | python3 -c 'import json, sys; a = json.load(sys.stdin)[\"attributes\"][0]; assert a[\"min\"] is None and a[\"max\"] is None and a[\"nonfinite\"] == 2, a'"
check "info of a NetCDF file gives what its gaps did (netcdf.split_trajectories and the rest; the bake's cache had them, info not); a --flight that is a directory is exit 2 naming it" bash -c "/usr/bin/python3 -c \"
import netCDF4
f = netCDF4.Dataset('$tmp/gaps.nc', 'w')
f.createDimension('trajectory', 2); f.createDimension('time', 5)
lon = f.createVariable('lon', 'f4', ('trajectory', 'time'), fill_value=-999.0)
lat = f.createVariable('lat', 'f4', ('trajectory', 'time'))
lon[:] = [[1, -999, 2, -999, 3], [1, 2, 3, 4, 5]]; lat[:] = [[1] * 5, [1] * 5]
f.close()\" && '$bin' info '$tmp/gaps.nc' --json | python3 -c 'import json, sys; m = json.load(sys.stdin)[\"metadata\"]; assert m[\"netcdf.split_trajectories\"] == \"1\" and m[\"netcdf.lines_from_splits\"] == \"2\" and m[\"netcdf.missing_observations\"] == \"2\", m' && '$bin' info '$tmp/gaps.nc' | grep -q '^gaps  *1 trajectories split at missing positions' && { '$bin' render '$tmp/t.lbc.h5' --flight '$tmp' --size 32x24 -o '$tmp/x.png' 2> '$tmp/flightdir.err'; [ \$? -eq 2 ]; } && grep -q 'is a directory, not a keyframe file' '$tmp/flightdir.err'"
check "mlabdb --layers 1 is a usage error (exit 1; it was exit 4 from the renderer)" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique mlabdb --layers 1 --size 32x24 -o '$tmp/x.png' 2> '$tmp/layers.err'; [ \$? -eq 1 ] && grep -q -- '--layers: mlabdb takes 2 to 64' '$tmp/layers.err'"
check "a mistyped flight is exit 2 with the name it meant" bash -c "'$bin' render '$tmp/t.lbc.h5' --flight orbit_zoom --size 32x24 -o '$tmp/x.png' 2> '$tmp/flight.err'; [ \$? -eq 2 ] && grep -qF \"orbit_zoom: neither a flight (orbit-zoom, orbit) nor a keyframe file: no such file; did you mean 'orbit-zoom'?\" '$tmp/flight.err'"
check "compare different sizes is an error" exit_code 2 "$bin" compare "$tmp/e.png" "$tmp/f_000.png"
printf 'not a png' > "$tmp/bad.png"
check "compare unreadable png exits 2" exit_code 2 "$bin" compare "$tmp/bad.png" "$tmp/e.png"
check "render capsules, stepping and packets" bash -c "'$bin' render '$tmp/t.lbc.h5' --geometry capsules --size 48x32 -o '$tmp/cap.png' && '$bin' render '$tmp/t.lbc.h5' --hits stepping --size 48x32 -o '$tmp/st.png' && '$bin' render '$tmp/t.lbc.h5' --packets --size 48x32 -o '$tmp/pk.png' --stats '$tmp/pk.json' && grep -q '\"packets\": true' '$tmp/pk.json'"
check "stepping with packets is a usage error" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --hits stepping --packets --size 32x24 -o "$tmp/x.png"
check "render uses the cached Embree buffers" bash -c "'$bin' render '$tmp/t.lbc.h5' --size 32x24 -o '$tmp/cb.png' --stats '$tmp/cb.json' && grep -q '\"bvh_from_cached_buffers\": true' '$tmp/cb.json'"
check "bench embree" bash -c "'$bin' bench embree --input '$tmp/c.binlines' --repeat 1 --json | grep -q '\"ratio_best\"'"
# The in-memory bench steps within --memory-budget: figures the same as unlimited, the peak
# within the budget, and what does not fit refused with the figures (exit 4).
check_budget "bench voxels under 64M: its records spilled, the same figures as unlimited and as bake's grid, the peak within it" /usr/bin/python3 -c "
import json, subprocess
run = lambda budget: json.loads(subprocess.run(['$bin', 'bench', 'voxels', '$tmp/c.binlines', '--grid', '640', '--repeat', '1', '--json', '--memory-budget', budget], check=True, capture_output=True, text=True, cwd='$tmp').stdout)
small, whole = run('64M'), run('unlimited')
keys = ['chords', 'representation_bytes', 'bytes_with_density', 'max_error_voxels', 'mean_error_voxels', 'resolution']
assert [small[k] for k in keys] == [whole[k] for k in keys], (small, whole)
# the grid bake builds, as stored: the same chords and arrays
subprocess.run(['$bin', 'bake', '$tmp/c.binlines', '-o', '$tmp/bv.lbc.h5', '--assets', 'voxels', '--grid', '640'], check=True, capture_output=True)
import h5py
with h5py.File('$tmp/bv.lbc.h5', 'r') as f:
    v = f['assets/voxels']
    size = lambda name: v[name].size * v[name].dtype.itemsize
    stored = (v['chords'].shape[0], size('offsets') + size('chords'), size('offsets') + size('chords') + size('line_counts') + sum(size(n) for n in v if n.startswith('density_')))
assert (whole['chords'], whole['representation_bytes'], whole['bytes_with_density']) == stored, (whole, stored)
assert small['spilled_bytes'] > 0 and whole['spilled_bytes'] == 0, (small, whole)
assert small['memory_budget_bytes'] == 64 << 20 and 0 < small['peak_rss_bytes'] <= 64 << 20, small
import os; assert not [f for f in os.listdir('$tmp') if 'bench-voxels' in f]"
check_budget "bench voxels: a grid whose chord counts pass the budget is refused (exit 4)" bash -c "'$bin' bench voxels '$tmp/c.binlines' --grid 768 --repeat 1 --memory-budget 60M 2> '$tmp/bvb.err'; [ \$? -eq 4 ] && grep -q \"bench voxels: the voxel grid's chord counts and density mip levels (28311552 voxels): about 44.43 MiB in memory, more than the memory budget of 60.00 MiB leaves\" '$tmp/bvb.err'"
check "bench voxels: lines past the budget are refused while read (exit 4)" bash -c "'$bin' bench voxels '$tmp/c.binlines' --repeat 1 --memory-budget 40M 2> '$tmp/bvr.err'; [ \$? -eq 4 ] && grep -q \"bench voxels: $tmp/c.binlines: read whole, its first .* points and their arrays' growth take about .* in memory, more than the .* the memory budget leaves for reading\" '$tmp/bvr.err'"
check_budget "bench tubes: a mesh past the budget is refused before it is built (exit 4)" bash -c "'$bin' bench tubes '$tmp/c.binlines' --repeat 1 --memory-budget 90M 2> '$tmp/btb.err'; [ \$? -eq 4 ] && grep -q 'bench tubes: the tube mesh of 495000 segments with 3 sides: about 82.79 MiB in memory, more than the memory budget of 90.00 MiB leaves' '$tmp/btb.err'"
check_budget "bench tubes within 130M: the peak within it, memcpy's buffers from what is left" python3 -c "
import json, subprocess
j = json.loads(subprocess.run(['$bin', 'bench', 'tubes', '$tmp/c.binlines', '--repeat', '1', '--json', '--memory-budget', '130M'], check=True, capture_output=True, text=True).stdout)
assert 0 < j['peak_rss_bytes'] <= 130 << 20 and j['memcpy_buffer_bytes'] < 130 << 20 and j['bytes_written'] > 0, j"
check_budget "bench embree: a BVH past the budget is refused (exit 4)" bash -c "'$bin' bench embree '$tmp/c.binlines' --repeat 1 --memory-budget 70M 2> '$tmp/beb.err'; [ \$? -eq 4 ] && grep -q \"Embree's BVH over 495000 segments needs more than the .* the memory budget leaves for the scene\" '$tmp/beb.err'"
# Vulkan on lavapipe (VK_ICD_FILENAMES from CTest), validation layer on
check "render ll (Vulkan) with validation" "$bin" render "$tmp/t.lbc.h5" --technique ll --validation --tf semi --frame 3 --frame-count 8 --size 96x64 -o "$tmp/ll.png" --stats "$tmp/ll.json" --depth-complexity "$tmp/lldc.png"
check "ll stats name the device and passes" bash -c "grep -q '\"gather\"' '$tmp/ll.json' && grep -q '\"device\"' '$tmp/ll.json'"
check "ll equals the reference (PSNR >= 45 dB)" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique reference --tf semi --frame 3 --frame-count 8 --size 96x64 -o '$tmp/r8.png' && '$bin' compare '$tmp/ll.png' '$tmp/r8.png' --json | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)[\"psnr_db\"] >= 45 else 1)'"
check "render opaque (Vulkan)" "$bin" render "$tmp/t.lbc.h5" --technique opaque --validation --tf opaque --size 64x48 -o "$tmp/op.png" --stats "$tmp/op.json"
check "raster stats: fragments and depth complexity only where counted (opaque had zeros), ll's fragments the sum of its counts" python3 -c "
import json
o = json.load(open('$tmp/op.json'))['frames'][0]
assert 'depth_complexity' not in o and 'fragments' not in o, o
l = json.load(open('$tmp/ll.json'))['frames'][0]
assert l['fragments'] > 0 and l['depth_complexity']['max'] > 0, l"
check "ll with a small --capacity: later frames of the size start from the grown pool, which never shrinks (every frame had started from 64 and regrown)" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique ll --capacity 64 --frames all --frame-count 6 --size 48x32 -o '$tmp/cap.png' --stats '$tmp/cap.json' > /dev/null 2>&1 && python3 -c \"
import json
f = json.load(open('$tmp/cap.json'))['frames']
c = [x['node_capacity'] for x in f]
assert f[0]['regrows'] >= 1 and c == sorted(c) and sum(x['regrows'] for x in f) < len(f), [(x['regrows'], x['node_capacity']) for x in f]\""
check "dp equals the reference (PSNR >= 45 dB)" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique dp --validation --tf semi --frame 3 --frame-count 8 --size 96x64 -o '$tmp/dp.png' --stats '$tmp/dp.json' && '$bin' compare '$tmp/dp.png' '$tmp/r8.png' --json | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)[\"psnr_db\"] >= 45 else 1)'"
check "dp stats: layers peeled = max depth complexity" python3 -c "import json; f=json.load(open('$tmp/dp.json'))['frames'][0]; assert f['layers'] == f['depth_complexity']['max'] > 0 and not f['layers_capped'], f"
for t in mlab mlabdb mboit wboit; do
  check "render $t (Vulkan) with validation" "$bin" render "$tmp/t.lbc.h5" --technique $t --validation --tf transparent --size 64x48 -o "$tmp/$t.png" --stats "$tmp/$t.json"
done
check "mlab stats name the critical section and k" python3 -c "import json; f=json.load(open('$tmp/mlab.json'))['frames'][0]; assert f['layers'] == 8 and f['critical_section'] in ('spin lock', 'interlock'), f"
check "mlabdb defaults to 4 nodes" python3 -c "import json; f=json.load(open('$tmp/mlabdb.json'))['frames'][0]; assert f['layers'] == 4, f"
check "mboit 8 trigonometric moments (Vulkan) with validation" "$bin" render "$tmp/t.lbc.h5" --technique mboit --moments 8 --moment-basis trigonometric --validation --tf transparent --size 64x48 -o "$tmp/mb8.png" --stats "$tmp/mb8.json"
check "mboit stats name basis, count and default bias" python3 -c "import json; m=json.load(open('$tmp/mb8.json'))['moments']; assert m == {'basis': 'trigonometric', 'count': 8, 'bias': 1.5e-5}, m"
check "mboit 8 moments use a third target" python3 -c "import json; a=json.load(open('$tmp/mboit.json'))['frames'][0]['frame_bytes']; b=json.load(open('$tmp/mb8.json'))['frames'][0]['frame_bytes']; assert b - a == 64 * 48 * 32, (a, b)"
check "mboit --moments 5 is a usage error" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique mboit --moments 5 --size 32x24 -o "$tmp/x.png"
check "mlab --layers 65 is a usage error" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique mlab --layers 65 --size 32x24 -o "$tmp/x.png"
check "wboit unknown weight is a usage error" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique wboit --wboit-weight 5 --size 32x24 -o "$tmp/x.png"
check "early termination only for embree, ll and rtx: a usage error" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique mboit --early-termination --size 32x24 -o "$tmp/x.png"
# Options the technique does not read are refused, naming them and what it reads, before any work.
check "render embree --sort --moments --device: refused, naming them, exit 1" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique embree --sort shell --moments 6 --device x -o '$tmp/own.png' 2> '$tmp/own.err'; [ \$? -eq 1 ] && grep -q -- '--sort, --moments, --device: not read by embree (embree reads --embree-geometry' '$tmp/own.err' && [ ! -e '$tmp/own.png' ]"
check "render ll --geometry --hits --packets: refused" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique ll --geometry bezier --hits stepping -o "$tmp/own.png"
check "render --early-termination with --no-early-termination: refused" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique ll --early-termination --no-early-termination -o "$tmp/own.png"
check "render --frame with --frames all: refused" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --frame 2 --frames all -o "$tmp/own.png"
check "depth-complexity (GPU) writes counts and stats" "$bin" depth-complexity "$tmp/t.lbc.h5" --validation --frame 3 --frame-count 8 --size 96x64 -o "$tmp/dc.png" --stats "$tmp/dc.json"
check "depth-complexity (CPU) agrees with the GPU" bash -c "'$bin' depth-complexity '$tmp/t.lbc.h5' --on cpu --frame 3 --frame-count 8 --size 96x64 --stats '$tmp/dc_cpu.json' && python3 -c \"import json; g=json.load(open('$tmp/dc.json'))['frames'][0]; c=json.load(open('$tmp/dc_cpu.json'))['frames'][0]; assert g['max'] > 0 and abs(g['fragments'] - c['fragments']) <= 0.01 * c['fragments'], (g, c)\""
check "depth-complexity max equals ll's" python3 -c "import json; g=json.load(open('$tmp/dc.json'))['frames'][0]; l=json.load(open('$tmp/ll.json'))['frames'][0]; assert g['max'] == l['depth_complexity']['max'], (g, l)"
check "depth-complexity without outputs prints the statistics" bash -c "'$bin' depth-complexity '$tmp/t.lbc.h5' --size 32x24 2>/dev/null | grep -q '^frame 0: depth complexity max [1-9]'"
check "depth-complexity without tubes is an error" exit_code 2 "$bin" depth-complexity "$tmp/v.lbc.h5" --size 32x24 -o "$tmp/x.png"
check "ll without tubes is an error" exit_code 2 "$bin" render "$tmp/v.lbc.h5" --technique ll --size 32x24 -o "$tmp/x.png"
check "unknown Vulkan device is an error" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique ll --device no-such-gpu --size 32x24 -o "$tmp/x.png"
# Voxel ray casting (CPU and Vulkan compute) and ray tracing's absence on lavapipe
check "vrc without voxels is an error" exit_code 2 "$bin" render "$tmp/t.lbc.h5" --technique vrc --size 32x24 -o "$tmp/x.png"
check "bake voxels next to tubes" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/t.lbc.h5' --assets tubes,voxels --grid 64 > /dev/null 2>&1"
# Every technique's flight frames the same box (the lines grown by the tubes' radius), so that
# each compares with the reference from the reference's camera (embree and tiles framed the
# capsules' box, the rest the tube mesh's).
check "every technique renders a frame from the same camera" bash -c "for t in reference embree ll tiles vrc; do '$bin' render '$tmp/t.lbc.h5' --technique \$t --frame 3 --frame-count 8 --size 32x24 -o '$tmp/cam-'\$t.png --stats '$tmp/cam-'\$t.json > /dev/null 2>&1 || exit 1; done
python3 - '$tmp' <<'PYEOF'
import json, sys
cameras = {t: json.load(open(f'{sys.argv[1]}/cam-{t}.json'))['frames'][0]['camera'] for t in ['reference', 'embree', 'll', 'tiles', 'vrc']}
assert all(c == cameras['reference'] for c in cameras.values()), cameras
PYEOF"
check "render --warm-up: the same frames, only the flight's written, the count in --stats" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique ll --frames all --frame-count 3 --size 32x24 -o '$tmp/cold.png' > /dev/null 2>&1 && '$bin' render '$tmp/t.lbc.h5' --technique ll --frames all --frame-count 3 --size 32x24 --warm-up 2 -o '$tmp/warm.png' --stats '$tmp/warm.json' > /dev/null 2>&1 && for f in 000 001 002; do cmp '$tmp/cold_'\$f.png '$tmp/warm_'\$f.png || exit 1; done && [ \$(ls '$tmp' | grep -c '^warm_') -eq 3 ] && grep -q '\"warm_up_frames\": 2' '$tmp/warm.json'"
check "render vrc on the CPU" "$bin" render "$tmp/t.lbc.h5" --technique vrc --tf semi --frame 3 --frame-count 8 --size 96x64 -o "$tmp/vrc.png" --stats "$tmp/vrc.json" --depth-complexity "$tmp/vrcdc.png"
check "render vrc on the GPU with validation" "$bin" render "$tmp/t.lbc.h5" --technique vrc --on gpu --validation --tf semi --frame 3 --frame-count 8 --size 96x64 -o "$tmp/vrcg.png" --stats "$tmp/vrcg.json"
check "vrc GPU and CPU agree (PSNR >= 45 dB)" bash -c "'$bin' compare '$tmp/vrcg.png' '$tmp/vrc.png' --json | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)[\"psnr_db\"] >= 45 else 1)'"
check "vrc resembles the reference (SSIM >= 0.8)" bash -c "'$bin' compare '$tmp/vrc.png' '$tmp/r8.png' --json | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)[\"ssim\"] >= 0.8 else 1)'"
check "vrc stats: grid, radius, hits, occupancy levels" python3 -c "import json; j=json.load(open('$tmp/vrc.json')); f=j['frames'][0]; assert j['grid']['resolution'][0] <= 64 and 0 < j['radius'] <= j['grid']['voxel_size'] and f['hits'] > 0 and f['voxels_visited'] > 0 and j['occupancy_levels'] > 1 and j['skip_empty_space'], j"
check "vrc --no-skip gives the same image" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique vrc --no-skip --tf semi --frame 3 --frame-count 8 --size 96x64 -o '$tmp/vrcns.png' && cmp '$tmp/vrcns.png' '$tmp/vrc.png'"
check "--on is a vrc option (usage error)" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique ll --on gpu --size 32x24 -o "$tmp/x.png"
check "rtx on lavapipe: one clear line, exit 4" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique rtx --size 32x24 -o '$tmp/rtx.png' 2> '$tmp/rtx.err'; rc=\$?; [ \$rc -eq 4 ] && [ \$(wc -l < '$tmp/rtx.err') -eq 1 ] && grep -q 'not supported on this device' '$tmp/rtx.err' && [ ! -e '$tmp/rtx.png' ]"
check "bake --assets rtx on lavapipe: one clear line, exit 4, the cache untouched" bash -c "cp '$tmp/t.lbc.h5' '$tmp/before.h5'; '$bin' bake '$tmp/c.binlines' -o '$tmp/t.lbc.h5' --assets tubes,voxels,rtx 2> '$tmp/bakertx.err' > /dev/null; rc=\$?; [ \$rc -eq 4 ] && [ \$(wc -l < '$tmp/bakertx.err') -eq 1 ] && grep -q 'rtx: ray tracing is not supported on this device' '$tmp/bakertx.err' && cmp '$tmp/t.lbc.h5' '$tmp/before.h5'"
# every output is checked before any work: nothing is rendered, generated or left behind
check "render -o x.jpg: refused before rendering, exit 3, nothing left" bash -c "'$bin' render '$tmp/t.lbc.h5' --technique reference --size 8000x8000 -o '$tmp/pre.jpg' 2> '$tmp/pre.err'; [ \$? -eq 3 ] && grep -q 'pre.jpg: unknown image format (use .png or .pfm)' '$tmp/pre.err' && [ ! -e '$tmp/pre.jpg' ]"
check "render --stats in a missing directory: exit 3 before the image is written" bash -c "'$bin' render '$tmp/t.lbc.h5' --size 32x24 -o '$tmp/pre.png' --stats '$tmp/nodir/pre.json' 2> '$tmp/pre.err'; [ \$? -eq 3 ] && grep -q 'the directory .*nodir does not exist' '$tmp/pre.err' && [ ! -e '$tmp/pre.png' ]"
check "synth to a format linebake cannot write: exit 3 before generating, the writable ones listed" bash -c "'$bin' synth clouds --scale 2 -o '$tmp/pre.nc' 2> '$tmp/pre.err'; [ \$? -eq 3 ] && grep -q 'pre.nc: writing netcdf is not supported (writable: ' '$tmp/pre.err' && [ ! -e '$tmp/pre.nc' ]"
check "depth-complexity -o x.txt and bake -o nodir/: exit 3" bash -c "'$bin' depth-complexity '$tmp/t.lbc.h5' -o '$tmp/pre.txt' 2> /dev/null; [ \$? -eq 3 ] && '$bin' bake '$tmp/c.binlines' -o '$tmp/nodir/pre.lbc.h5' 2> '$tmp/pre.err'; [ \$? -eq 3 ] && grep -q 'nodir does not exist' '$tmp/pre.err' && [ ! -e '$tmp/nodir' ]"
check "render --tf semii: the presets and the nearest named, exit 1, before any work" bash -c "'$bin' render '$tmp/t.lbc.h5' --tf semii -o '$tmp/pre.png' 2> '$tmp/pre.err'; [ \$? -eq 1 ] && grep -q \"semii: neither a transfer-function preset (opaque, semi, transparent) nor a file; did you mean 'semi'?\" '$tmp/pre.err' && [ ! -e '$tmp/pre.png' ]"
check "bench render --json: per technique GPU passes, wall, memory, PSNR against the reference, a warm-up frame" python3 -c "
import json, subprocess
j = json.loads(subprocess.run(['$bin', 'bench', 'render', '$tmp/t.lbc.h5', '--techniques', 'reference,ll,vrc,rtx', '--frames', '2', '--size', '64x48', '--json'], check=True, capture_output=True, text=True).stdout)
assert j['size'] == [64, 48] and j['frames'] == 2 and j['warm_up'] == 1 and len(j['runs']) == 1, j
# The build the figures came from, as version names it.
version = json.loads(subprocess.run(['$bin', 'version', '--json'], check=True, capture_output=True, text=True).stdout)
assert (j['linebake'], j['source_revision']) == (version['linebake'], version['source_revision']), (j, version)
run = j['runs'][0]
assert run['cache'] == 't' and run['segments'] == 495000, run
rows = {r['technique']: r for r in run['rows']}
# One frame first, not counted, in every row that rendered.
assert all(r['warm_up_s'] > 0 for r in rows.values() if 'skipped' not in r), rows
assert list(rows) == ['reference', 'll', 'vrc', 'rtx'] and all(r['transfer_function'] == 'semi' for r in rows.values()), rows
ll = rows['ll']
assert ll['frames'] == 2 and 'llvmpipe' in ll['device'] and ll['frame_bytes'] > 0, ll
assert 0 < ll['gpu_ms']['median'] <= ll['gpu_ms']['max'] and {'gather', 'resolve'} <= set(ll['passes']), ll
assert ll['psnr_db'] >= 50 and ll['ssim'] > 0.99, ll  # exact against exact
vrc = rows['vrc']
assert vrc['device'] == 'CPU' and 'gpu_ms' not in vrc and vrc['wall_s']['median'] > 0 and 10 < vrc['psnr_db'] < 60, vrc
assert 'psnr_db' not in rows['reference'] and rows['reference']['frames'] == 2, rows['reference']
assert 'ray tracing is not supported' in rows['rtx'].get('skipped', '') or rows['rtx']['frames'] == 2, rows['rtx']"
check "bench render tiles-triangles: tiles over the tube mesh, exact against the reference; tiles-raster-order; tiles-strips; tiles-pixel-hits; tiles-late-shading; --warm-up 0" python3 -c "
import json, subprocess
variants = ['tiles', 'tiles-triangles', 'tiles-raster-order', 'tiles-strips', 'tiles-crowded-strips', 'tiles-pixel-hits', 'tiles-triangles-pixel-hits', 'tiles-late-shading', 'tiles-triangles-late-shading', 'tiles-pixel-hits-late-shading']
j = json.loads(subprocess.run(['$bin', 'bench', 'render', '$tmp/t.lbc.h5', '--techniques', ','.join(variants), '--frames', '1', '--size', '64x48', '--warm-up', '0', '--json'], check=True, capture_output=True, text=True).stdout)
rows = {r['technique']: r for r in j['runs'][0]['rows']}
assert list(rows) == variants, rows
assert j['warm_up'] == 0 and not any('warm_up_s' in r for r in rows.values()), rows
# The old tile order, and four workgroups a tile (every tile; the crowded, and every tile of a
# walk over fewer than 512, so here every tile too): the same image.
for v in ('tiles-raster-order', 'tiles-strips', 'tiles-crowded-strips', 'tiles-pixel-hits', 'tiles-late-shading', 'tiles-pixel-hits-late-shading'):
    assert rows[v]['psnr_db'] == rows['tiles']['psnr_db'], (v, rows)
# Each pixel's own hits and late shading, over the tube mesh too: the same image.
for v in ('tiles-triangles-pixel-hits', 'tiles-triangles-late-shading'):
    assert rows[v]['psnr_db'] == rows['tiles-triangles']['psnr_db'], (v, rows)
# 64x48: 12 tiles, each walked at least once.
whole, strips, crowded = (rows[t]['tiles']['frames'][0] for t in ('tiles', 'tiles-strips', 'tiles-crowded-strips'))
assert whole['workgroups'] >= 12 and strips['workgroups'] == 4 * whole['workgroups'] == crowded['workgroups'], (whole, strips, crowded)
# Late shading's second tests found every hit again; the other variants do not report it.
assert all(rows[v]['tiles']['frames'][0]['late_misses'] == 0 for v in variants if 'late' in v), rows
assert 'late_misses' not in whole, whole
# What tiles' time follows, per frame, and its composite split into the first walk and the rest.
t = rows['tiles']['tiles']
assert len(t['frames']) == 1 and t['frames'][0]['keys'] > 0 and t['frames'][0]['walks'] >= 1, t
assert t['frames'][0]['max_tile_keys'] <= t['frames'][0]['keys'], t
walks = t['first_walk_ms']['median'] + t['walks_again_ms']['median']
assert abs(walks - rows['tiles']['passes']['composite']['median']) <= 1e-6 * max(walks, 1), (t, rows['tiles']['passes'])
assert rows['tiles-raster-order']['tiles']['frames'][0]['crowded_tiles'] == 0, rows
for r in rows.values():
    assert r['frames'] == 1 and {'bin', 'sort', 'composite'} <= set(r['passes']), r
assert rows['tiles-triangles']['psnr_db'] >= 50, rows  # the reference's surface
assert rows['tiles']['psnr_db'] < rows['tiles-triangles']['psnr_db'], rows  # capsules: another"
check "bench render: a Markdown table, unknown techniques refused before any work" bash -c "'$bin' bench render '$tmp/t.lbc.h5' --techniques wboit --frames 1 --size 32x24 2>/dev/null | grep -q '^| t (495,000) | semi | wboit | llvmpipe' && '$bin' bench render '$tmp/t.lbc.h5' --techniques wbiot 2> '$tmp/bench.err'; [ \$? -ne 0 ] && grep -q \"unknown technique 'wbiot'\" '$tmp/bench.err'"
check "bench render --size under 11x11 refused before any work (SSIM's window; it had failed after rendering)" bash -c "'$bin' bench render '$tmp/t.lbc.h5' --techniques wboit --frames 1 --size 10x40 > '$tmp/bs.out' 2> '$tmp/bs.err'; [ \$? -eq 1 ] && grep -q 'at least 11x11 pixels' '$tmp/bs.err' && ! grep -q 'bench render: t' '$tmp/bs.err' && [ ! -s '$tmp/bs.out' ]"
check "bench render --every-hit: embree's interval walk and every hit, the same image" python3 -c "
import json, subprocess
def bench(*extra):
    return json.loads(subprocess.run(['$bin', 'bench', 'render', '$tmp/t.lbc.h5', '--techniques', 'embree', '--tf', 'opaque', '--frames', '1', '--size', '64x48', '--json', *extra], check=True, capture_output=True, text=True).stdout)
walk, every = bench(), bench('--every-hit')
assert walk['every_hit'] is False and every['every_hit'] is True, (walk, every)
w, e = walk['runs'][0]['rows'][0], every['runs'][0]['rows'][0]
assert w['every_hit'] is False and e['every_hit'] is True, (w, e)
assert e['traversals'] == 64 * 48 and e['rays_stopped_opaque'] == 0, e
assert w['rays_stopped_opaque'] > 0 and w['front_hits'] < e['front_hits'], (w, e)
assert w['psnr_db'] == e['psnr_db'] and w['ssim'] == e['ssim'], (w, e)  # the same image"
# bench shaders: the compiler's statistics where the driver reports them. lavapipe does not;
# RADV (the same Mesa package) compiles for an AMD GPU that is not there with RADV_FORCE_FAMILY.
check "bench shaders on lavapipe: exit 4 naming the extension it lacks" bash -c "'$bin' bench shaders 2> '$tmp/shaders.err'; [ \$? -eq 4 ] && grep -q 'no VK_KHR_pipeline_executable_properties' '$tmp/shaders.err'"
check "bench shaders --shaders names nothing: usage error listing the shaders" bash -c "'$bin' bench shaders --shaders tiles_compsite 2> '$tmp/shaders.err'; [ \$? -eq 1 ] && grep -q \"no compute shader's name contains 'tiles_compsite'.*tiles_composite.comp:exits\" '$tmp/shaders.err'"
radv_icd=$(ls /usr/share/vulkan/icd.d/radeon_icd.*.json 2>/dev/null | head -1)
check "bench shaders on RADV's null device (navi21): registers of every compute shader; a deeper window takes more" env VK_ICD_FILENAMES="$radv_icd" RADV_FORCE_FAMILY=navi21 python3 -c "
import json, subprocess
out = subprocess.run(['$bin', 'bench', 'shaders', '--json'], check=True, capture_output=True, text=True).stdout
j = json.loads(out)
assert 'NAVI21' in j['device'] and j['driver'] == 'radv', j['device']
shaders = {s['shader']: s for s in j['shaders']}
assert len(shaders) >= 20 and 'vrc.comp' in shaders and 'radix_scatter.comp:subgroups' in shaders, sorted(shaders)
for name, s in shaders.items():
    v = s['statistics']['VGPRs']
    assert isinstance(v, int) and 0 < v <= 256 and s['subgroup_size'] in (32, 64), (name, s)
# tiles' composite holds its window of pending hits in registers: 8 hits (lavapipe's), 16 (exits),
# 64 (deep, which does not fit: spilled to scratch memory).
plain, exits, deep = (shaders['tiles_composite.comp' + v]['statistics'] for v in ('', ':exits', ':deep'))
assert plain['VGPRs'] < exits['VGPRs'] <= deep['VGPRs'], (plain, exits, deep)
assert deep['Scratch size'] > 0 and plain['Scratch size'] == 0, (plain, deep)
# Late shading keeps no colours in the window: fewer registers, and the 64-hit window of the
# walks again mostly out of scratch memory (docs/tiles.md, Shading late).
for c in ('tiles_composite.comp', 'tiles_composite_triangles.comp'):
    s = {v: shaders[c + v]['statistics'] for v in (':exits', ':exits-late', ':deep', ':deep-late')}
    assert s[':exits-late']['VGPRs'] < s[':exits']['VGPRs'], (c, s)
    assert s[':deep-late']['Scratch size'] < s[':deep']['Scratch size'], (c, s)
text = subprocess.run(['$bin', 'bench', 'shaders', '--shaders', 'tiles_bin', '--statistics', 'VGPRs,Scratch'], check=True, capture_output=True, text=True).stdout
assert 'tiles_bin.comp (Compute Shader, subgroup' in text and 'tiles_bin_triangles.comp' in text and 'tiles_composite' not in text, text
assert 'VGPRs' in text and 'Scratch size' in text and 'Instructions' not in text, text
# A statistic this driver does not report: a warning that lists those it does.
warned = subprocess.run(['$bin', 'bench', 'shaders', '--shaders', 'tiles_ranges', '--statistics', 'regs'], check=True, capture_output=True, text=True).stderr
assert \"radv reports no statistic named like 'regs'; it reports: \" in warned and 'VGPRs' in warned, warned"
check "bench shaders: every compute shader compiles for GCN, CDNA2 and RDNA2 (RADV's null devices vega10, aldebaran, navi21)" python3 -c "
import json, os, subprocess
names = []
for family in ('vega10', 'aldebaran', 'navi21'):
    env = dict(os.environ, VK_ICD_FILENAMES='$radv_icd', RADV_FORCE_FAMILY=family)
    out = subprocess.run(['$bin', 'bench', 'shaders', '--statistics', 'VGPRs', '--json'], env=env, check=True, capture_output=True, text=True).stdout
    names.append(sorted(s['shader'] for s in json.loads(out)['shaders']))
assert names[0] == names[1] == names[2] and len(names[0]) >= 20, names"
check "--rt-geometry is an rtx option (usage error)" exit_code 1 "$bin" render "$tmp/t.lbc.h5" --technique vrc --rt-geometry capsules --size 32x24 -o "$tmp/x.png"
check "bake --rtx-geometry must be triangles or capsules" exit_code 1 "$bin" bake "$tmp/c.binlines" -o "$tmp/t.lbc.h5" --assets rtx --rtx-geometry spheres
# Pipelines: pipelines/ci.json end to end, reuse, --dry-run, a failing step
pipes="$(dirname "$0")/../pipelines"
check "run the ci pipeline" bash -c "'$bin' run '$pipes/ci.json' -o '$tmp/ci' > '$tmp/run.out' 2> '$tmp/run.err' && grep -q 'report.md' '$tmp/run.out' && grep -q 'report.html' '$tmp/run.out' && [ ! -e '$tmp/ci/.linebake-run.lock' ]"
check "ci report: every technique has PSNR/SSIM, rtx skipped with its reason" python3 -c "
import json; j=json.load(open('$tmp/ci/report.json')); r={x['technique']: x for x in j['results']}
assert 'ray tracing' in r['rtx']['skipped'], r['rtx']
for t in ('embree', 'll', 'mboit', 'vrc-cpu'): assert r[t]['mean_ssim'] > 0.7 and len(r[t]['frames']) == 2, r[t]
assert r['ll']['mean_psnr_db'] >= 30, r['ll']
assert j['caches'][0]['name'] == 'aneurysm'"
check "ci report.md has Table 1 and the quality table" bash -c "grep -q '## Table 1' '$tmp/ci/report.md' && grep -q '| ll |' '$tmp/ci/report.md'"
check "the ci pipeline's renders warm up a frame first, and the reports say so" bash -c "grep -q 'each technique having rendered 1 untimed warm-up frame first' '$tmp/ci/report.md' && grep -q 'untimed warm-up frame' '$tmp/ci/report.html' && grep -q '\"warm_up_frames\": 1' '$tmp/ci/aneurysm/ll-semi.json'"
check "ci report.md links the plots, which exist" bash -c "grep -q '](plots/aneurysm-semi-time.svg)' '$tmp/ci/report.md' && for p in time psnr ssim memory; do grep -q '<polyline' '$tmp/ci/plots/aneurysm-semi-'\$p.svg || exit 1; done"
check "report.html is self-contained: every image a data: URI, no external resources" bash -c "h='$tmp/ci/report.html'; [ \$(grep -o '<img' \"\$h\" | wc -l) -gt 0 ] && ! grep -Eo '(src|href)=\"[^\"]*' \"\$h\" | grep -Ev '^(src=\"data:image/png;base64,|href=\"(#|aneurysm/))' | grep -q ."
check "report.html loads in headless Chromium without errors and shows every image" bash -c "h='$tmp/ci/report.html'; n=\$(grep -o '<img' \"\$h\" | wc -l); chromium --headless --no-sandbox --disable-gpu --enable-logging=stderr --v=0 --virtual-time-budget=10000 --dump-dom \"file://\$h\" > '$tmp/dom.html' 2> '$tmp/chromium.err'; grep -q \"data-images=\\\"\$n/\$n\\\"\" '$tmp/dom.html' && ! grep -Eq 'Uncaught|CONSOLE.*[Ee]rror' '$tmp/chromium.err'"
check "the shipped paper pipelines (YAML) plan, dp left out where the file says" bash -c "'$bin' run '$pipes/paper-small' --dry-run -o '$tmp/ps' > '$tmp/ps.txt' && grep -q '^skip render/clouds/dp/semi: left out of this pipeline on clouds' '$tmp/ps.txt' && grep -q '^run render/clouds/mboit/transparent' '$tmp/ps.txt' && '$bin' run '$pipes/paper.yaml' --dry-run -o '$tmp/pp' | grep -q '^run render/clouds/dp/transparent: .*--size 1920x1080'"
check "a second run reuses every step" bash -c "'$bin' run '$pipes/ci.json' -o '$tmp/ci' 2>&1 >/dev/null | grep -q ' 0 step(s) run, 14 reused, 3 skipped'"
check "run: a deleted depth-complexity image renders its step again (the step had been reused, and the report left that frame out); a technique that writes none (mboit) is still reused" bash -c "rm '$tmp/ci/aneurysm/reference-semi-dc_001.png' && '$bin' run '$pipes/ci.json' -o '$tmp/ci' --dry-run > '$tmp/dc.txt' && grep -q '^run render/aneurysm/reference/semi' '$tmp/dc.txt' && grep -q '^reuse render/aneurysm/mboit/semi' '$tmp/dc.txt' && '$bin' run '$pipes/ci.json' -o '$tmp/ci' > /dev/null 2>&1 && [ -e '$tmp/ci/aneurysm/reference-semi-dc_001.png' ] && ! ls '$tmp/ci/aneurysm' | grep -q '^mboit-semi-dc'"
check "--dry-run after a change lists what reruns" bash -c "sed 's/\"heap\"/\"shell\"/' '$pipes/ci.json' > '$tmp/ci2.json' && '$bin' run '$tmp/ci2.json' -o '$tmp/ci' --dry-run > '$tmp/dry.txt' && grep -q '^run render/aneurysm/ll/semi' '$tmp/dry.txt' && grep -q '^reuse render/aneurysm/mboit/semi' '$tmp/dry.txt' && [ \$(grep -c '^run ' '$tmp/dry.txt') -eq 3 ]"
check "Table 1 lists the assets the pipeline bakes, not others its cache keeps (an embree group added by hand had been listed)" bash -c "'$bin' bake '$tmp/ci/aneurysm.lbc.h5' --assets tubes,voxels,embree --grid 32 > /dev/null 2>&1 && h5ls '$tmp/ci/aneurysm.lbc.h5/assets' | grep -q embree && '$bin' run '$pipes/ci.json' -o '$tmp/ci' > /dev/null 2>&1 && grep -A3 '## Table 1' '$tmp/ci/report.md' | grep -q 'voxels (VRC) size' && ! grep -A3 '## Table 1' '$tmp/ci/report.md' | grep -q embree"
check "a failing step is named, exit 4, finished outputs kept" bash -c "sed 's/\"sort\": \"heap\"/\"sort\": \"heap\", \"memory-budget\": \"1K\"/' '$pipes/ci.json' > '$tmp/ci3.json' && '$bin' run '$tmp/ci3.json' -o '$tmp/ci3' > /dev/null 2> '$tmp/fail.err'; [ \$? -eq 4 ] && grep -q 'step render/aneurysm/ll/semi failed' '$tmp/fail.err' && [ -e '$tmp/ci3/aneurysm/embree-semi_001.png' ] && [ ! -e '$tmp/ci3/report.md' ]"
# A small pipeline of two data sets: the runs below change one thing each.
cat > "$tmp/small.json" <<'EOF'
{"name": "small", "datasets": [{"name": "an", "source": "synth:aneurysm?scale=0.005"},
                               {"name": "cv", "source": "synth:convection?scale=0.005"}],
 "assets": {"assets": ["tubes"]},
 "techniques": [{"technique": "reference", "datasets": ["cv"]}, "embree", "wboit"],
 "flight": "kf.json", "frames": 2, "size": "32x24"}
EOF
cat > "$tmp/kf.json" <<'EOF'
{"keyframes": [{"eye": [0, 2, 12], "target": [0, 0.5, 0], "up": [0, 1, 0], "fov": 45},
               {"eye": [6, 2, 10], "target": [0, 0.5, 0], "up": [0, 1, 0], "fov": 45}]}
EOF
check "run: a file where a step's directory goes is exit 3 naming it, before any step runs" bash -c "mkdir -p '$tmp/way1' && touch '$tmp/way1/an' && '$bin' run '$tmp/small.json' -o '$tmp/way1' > /dev/null 2> '$tmp/way1.err'; [ \$? -eq 3 ] && grep -qF \"$tmp/way1/an: is in the way: the run writes a directory here\" '$tmp/way1.err' && [ ! -e '$tmp/way1/an.lbc.h5' ] && [ -f '$tmp/way1/an' ]"
check "run: a directory where a report goes is exit 3 naming it, kept (an empty one had been removed)" bash -c "mkdir -p '$tmp/way2/report.md' '$tmp/way3/report.html' && touch '$tmp/way2/report.md/notes' && for d in way2/report.md way3/report.html; do '$bin' run '$tmp/small.json' -o \$(dirname '$tmp/'\$d) > /dev/null 2> '$tmp/way.err'; [ \$? -eq 3 ] && grep -qF \"$tmp/\$d: is a directory where the run writes a file\" '$tmp/way.err' && [ -d '$tmp/'\$d ] || exit 1; done"
check "run: where the reference does not run, the others are rendered and reported 'not compared' (the report had failed on a missing compare file)" bash -c "'$bin' run '$tmp/small.json' -o '$tmp/small' > /dev/null 2>&1 && python3 -c \"
import json; j=json.load(open('$tmp/small/report.json')); r={(x['dataset'], x['technique']): x for x in j['results']}
assert 'its reference, reference, does not run here' in r[('an', 'embree')]['not_compared'], r[('an', 'embree')]
assert 'mean_ssim' not in r[('an', 'embree')] and r[('cv', 'embree')]['mean_ssim'] > 0.5
assert j['warm_up'] == 1
\" && grep -q '| embree | .* | not compared \[' '$tmp/small/report.md'"
check "run: an edited key-frame file renders again (it had been reused)" bash -c "sed -i 's/\"fov\": 45}]}/\"fov\": 30}]}/' '$tmp/kf.json' && '$bin' run '$tmp/small.json' -o '$tmp/small' --dry-run | grep -q '^run render/an/embree/semi'"
check "run: -o spelled 'dir/' or 'parent/./dir' reuses what 'dir' ran" bash -c "sed -i 's/\"fov\": 30}]}/\"fov\": 45}]}/' '$tmp/kf.json' && for o in '$tmp/small/' '$tmp/./small'; do '$bin' run '$tmp/small.json' -o \"\$o\" --dry-run > '$tmp/spelled.txt' && grep -q '^reuse render/an/embree/semi' '$tmp/spelled.txt' && ! grep -q '^run ' '$tmp/spelled.txt' || exit 1; done"
check "run: a failing step loses its record and the stale reports and plots go (an interrupted step had kept its record beside new outputs)" bash -c "ls '$tmp/small/plots' | grep -q '\\.svg\$' && sed 's/\"wboit\"]/{\"technique\": \"wboit\", \"options\": {\"memory-budget\": \"1K\"}}]/' '$tmp/small.json' > '$tmp/small-fail.json' && '$bin' run '$tmp/small-fail.json' -o '$tmp/small' > /dev/null 2>&1; [ \$? -eq 4 ] && [ ! -e '$tmp/small/report.html' ] && [ ! -e '$tmp/small/report.json' ] && [ -z \"\$(ls '$tmp/small/plots' | grep '\\.svg\$')\" ] && '$bin' run '$tmp/small.json' -o '$tmp/small' --dry-run | grep -q '^run render/an/wboit/semi'"
pipeline_refused() {  # pipeline_refused NAME JSON EXPECTED-TEXT
  printf '%s' "$2" > "$tmp/refused-$1.json"
  check "pipeline refused: $1" bash -c "'$bin' run '$tmp/refused-$1.json' --dry-run > /dev/null 2> '$tmp/refused-$1.err'; [ \$? -eq 2 ] && grep -qF -- \"$3\" '$tmp/refused-$1.err'"
}
pipeline_refused name-leaving-out '{"name": "../../x", "datasets": [{"name": "a", "source": "synth:aneurysm"}], "techniques": ["reference"]}' "name: '../../x': a name without '/'"
pipeline_refused empty-output '{"output": "", "datasets": [{"name": "a", "source": "synth:aneurysm"}], "techniques": ["reference"]}' 'output: an empty output directory'
pipeline_refused tf-same-files '{"output": "o", "datasets": [{"name": "a", "source": "synth:aneurysm"}], "techniques": ["reference"], "transfer_functions": ["semi", "semi.json"]}' "'semi' and 'semi.json' would write the same files"
pipeline_refused asset-not-baked '{"output": "o", "datasets": [{"name": "a", "source": "synth:aneurysm"}], "assets": {"assets": ["voxels"]}, "techniques": ["reference"]}' "techniques[0]: reference reads the cache's tubes, which the pipeline's assets do not bake"
pipeline_refused dataset-cache-name '{"output": "o", "datasets": [{"name": "a", "source": "synth:aneurysm"}, {"name": "a.lbc.h5", "source": "synth:aneurysm"}], "techniques": ["reference"]}' "one data set's folder would be the other's cache file"
# Pipeline typos fail --dry-run with the file, the JSON path and the reason; nothing is run.
typo() {  # typo NAME SED-EXPRESSION EXPECTED-TEXT
  sed "$2" "$pipes/ci.json" > "$tmp/typo-$1.json"
  check "pipeline typo $1: --dry-run fails with its JSON path" bash -c "'$bin' run '$tmp/typo-$1.json' -o '$tmp/typo-$1' --dry-run > /dev/null 2> '$tmp/typo-$1.err'; [ \$? -eq 2 ] && grep -qF -- \"$3\" '$tmp/typo-$1.err' && [ ! -e '$tmp/typo-$1' ]"
}
typo technique 's/"embree",/"embre",/' 'techniques[1]: unknown technique'
typo sort-value 's/"sort": "heap"/"sort": "hep"/' "techniques[2].options: --sort: unknown 'hep' (insertion, shell, heap, quick-hybrid); did you mean 'heap'?"
typo sort-name 's/"sort": "heap"/"sortt": "heap"/' "techniques[2].options: unknown option 'sortt'; did you mean 'sort'?"
typo mlabdb-layers 's/"mboit",/{"technique": "mlabdb", "options": {"layers": 1}},/' "techniques[3].options.layers: mlabdb takes 2 to 64 layers, not 1"
typo option-of-another 's/"sort": "heap"/"moments": 6/' 'techniques[2].options: --moments: not read by ll'
typo tf 's/"semi"\]/"semmi"]/' "transfer_functions[0]: semmi: neither a transfer-function preset (opaque, semi, transparent) nor a file; did you mean 'semi'?"
typo size 's/"64x48"/"64x-36"/' 'size:'
typo flight 's/"orbit-zoom"/"orbit_zoom"/' "flight: 'orbit_zoom' is neither orbit-zoom, orbit nor a keyframe file; did you mean 'orbit-zoom'?"
typo grid 's/"grid": 32/"grid": "3x"/' 'assets: --grid'
typo size-of-a-technique 's/"sort": "heap"/"size": "32x24"/' 'techniques[2].options.size: set by the pipeline for every render'
typo cache-output 's/"grid": 32/"output": "x.lbc.h5"/' 'assets.output: set by the pipeline for every bake'
typo warm-up-of-a-technique 's/"sort": "heap"/"warm-up": 3/' 'techniques[2].options.warm-up: set by the pipeline for every render (its technique, transfer functions, flight, frames, warm_up'
typo size-below-ssim 's/"64x48"/"8x8"/' "size: '8x8': the report compares frames by SSIM, which needs at least 11x11 pixels"
typo synth-name 's/synth:aneurysm/synth:aneurysn/' "datasets[0].source: synth:aneurysn?scale=0.01: unknown synthetic data set 'aneurysn' (aneurysm, convection, turbulence, clouds); did you mean 'aneurysm'?"
typo synth-scale 's/scale=0.01/scale=1e9/' "'1e9' is not a number from 1e-06 to 100"
typo missing-source 's/synth:aneurysm?scale=0.01/nothere.binlines/' "nothere.binlines': no such file (a source is found relative to the pipeline file)"
typo tf-twice 's/"semi"\]/"semi", "semi"]/' "transfer_functions: 'semi' appears twice"
check "run into a directory another run holds: exit 3, nothing recorded; into a file: exit 3" bash -c "mkdir -p '$tmp/held' && { flock '$tmp/held/.linebake-run.lock' sleep 60 & holder=\$!; } && for i in \$(seq 200); do flock -n '$tmp/held/.linebake-run.lock' true || break; sleep 0.05; done; '$bin' run '$pipes/ci.json' -o '$tmp/held' > /dev/null 2> '$tmp/held.err'; rc=\$?; pkill -P \$holder sleep; wait; [ \$rc -eq 3 ] && grep -q 'another linebake run is writing into this directory' '$tmp/held.err' && [ ! -e '$tmp/held/.linebake-run.json' ] && touch '$tmp/afile' && { '$bin' run '$pipes/ci.json' -o '$tmp/afile' 2> /dev/null; [ \$? -eq 3 ]; }"
check "compare: grey against colour and images under 11x11 are exit 2 naming the image; an error image as PFM" bash -c "cd '$tmp' && '$bin' compare '$tmp/dep.png' '$tmp/dep.png' --error-image grey.png > /dev/null && { '$bin' compare grey.png '$tmp/dep.png' 2> grey.err; [ \$? -eq 2 ]; } && grep -q 'grey.png: 1 channel (grey), but the reference .*dep.png has 3 channels' grey.err && printf 'PF\n5 5\n-1\n' > tiny.pfm && head -c 300 /dev/zero >> tiny.pfm && { '$bin' compare tiny.pfm tiny.pfm 2> tiny.err; [ \$? -eq 2 ]; } && grep -q 'tiny.pfm: 5x5: SSIM needs images of at least 11x11 pixels' tiny.err && '$bin' compare '$tmp/dep.png' '$tmp/dep.png' --error-image e.pfm > /dev/null && head -c 3 e.pfm | grep -q '^Pf'"
# A 20000x20000 grey PNG of 400 KB (zeros deflate 1000 to 1): 1.49 GiB as floats. Under a 1G
# budget compare refuses it before allocating (exit 4, naming the file and the bytes; under
# ulimit -v an allocation of its pixels would fail otherwise); before 2026-11-30 compare held
# about 130 bytes a pixel of two such images and met the OOM killer.
check "compare: an image past --memory-budget is exit 4 naming the file, before its pixels are allocated" bash -c "/usr/bin/python3 -c \"
import struct, sys, zlib
def chunk(kind, data):
    return struct.pack('>I', len(data)) + kind + data + struct.pack('>I', zlib.crc32(kind + data))
z = zlib.compressobj(9)
row = bytes(20001)
body = b''.join(z.compress(row) for _ in range(20000)) + z.flush()
open(sys.argv[1], 'wb').write(b'\\x89PNG\\r\\n\\x1a\\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', 20000, 20000, 8, 0, 0, 0, 0)) + chunk(b'IDAT', body) + chunk(b'IEND', b''))
\" '$tmp/wide_zero.png' && (ulimit -v 1200000; '$bin' compare '$tmp/wide_zero.png' '$tmp/wide_zero.png' --memory-budget 1G 2> '$tmp/wide_zero.err'); [ \$? -eq 4 ] && grep -q 'wide_zero.png: 20000x20000, 1 channel, takes 1.49 GiB as floats and 381.62 MiB to decode, more than the .* the memory budget leaves; raise --memory-budget' '$tmp/wide_zero.err'"
check "run -o '' is a usage error (it was ignored); a PFM whose scale is NaN is not an image" bash -c "'$bin' run '$pipes/ci.json' -o '' --dry-run 2> '$tmp/emptyo.err'; [ \$? -eq 1 ] && grep -q -- '-o: an empty value names no file and no setting' '$tmp/emptyo.err' && printf 'Pf\n2 2\nnan\n' > '$tmp/nan.pfm' && head -c 16 /dev/zero >> '$tmp/nan.pfm' && { '$bin' compare '$tmp/nan.pfm' '$tmp/nan.pfm' 2> '$tmp/nanpfm.err'; [ \$? -eq 2 ]; } && grep -q 'nan.pfm: header: implausible size or scale' '$tmp/nanpfm.err'"
# A probe's findings (2026-11-30), each reproduced before its fix.
check "an empty option value is exit 1 naming the option (render -o '' had failed on the format, depth-complexity --stats '' and compare --error-image '' were ignored, info '' had said no such file, convert -o '' that -o is required, export -o '' the format)" bash -c "for cmd in \"render '$tmp/c.lbc.h5' -o ''\" \"depth-complexity '$tmp/c.lbc.h5' --size 16x16 --stats ''\" \"compare '$tmp/e.png' '$tmp/e.png' --error-image ''\" \"convert '$tmp/c.binlines' -o ''\" \"export '$tmp/c.lbc.h5' -o ''\" \"export '$tmp/c.lbc.h5' --glb ''\"; do eval \"'$bin' \$cmd\" 2> '$tmp/empty.err'; [ \$? -eq 1 ] && grep -q -- ': an empty value names no file and no setting; give one, or leave' '$tmp/empty.err' || exit 1; done; '$bin' info '' 2> '$tmp/empty.err'; [ \$? -eq 1 ] && grep -q 'input: an empty value names no file' '$tmp/empty.err'"
check "a list option's empty item is exit 1 naming the option and the value (CLI11 had dropped empty items, and --techniques ',,' had taken the next argument as its value); items split at commas and across repeats" bash -c "for cmd in \"bench render '$tmp/c.lbc.h5' --techniques ,, --frames 1|--techniques: an empty item in ',,'\" \"bench render '$tmp/c.lbc.h5' --techniques ll,,tiles|--techniques: an empty item in 'll,,tiles'\" \"bench render '$tmp/c.lbc.h5' --tf semi,|--tf: an empty item in 'semi,'\" \"bake '$tmp/c.binlines' -o '$tmp/items.lbc.h5' --assets tubes,|--assets: an empty item in 'tubes,'\" \"convert '$tmp/c.binlines' -o '$tmp/items.vtp' --derive ,curvature|--derive: an empty item in ',curvature'\" \"bench shaders --statistics VGPRs,|--statistics: an empty item\" \"bench render '$tmp/c.lbc.h5' --techniques ll,nosuch|unknown technique 'nosuch'\" \"bench render '$tmp/c.lbc.h5' --techniques ll --techniques nosuch|unknown technique 'nosuch'\"; do eval \"'$bin' \${cmd%%|*}\" 2> '$tmp/items.err'; [ \$? -eq 1 ] && grep -qF -- \"\${cmd#*|}\" '$tmp/items.err' || { cat '$tmp/items.err'; exit 1; }; done; ! ls '$tmp'/items.* 2>/dev/null | grep -v items.err"
check "bench with an unknown kind or none is exit 1 naming it and the kinds (CLI11 had said 'A subcommand is required' of both)" bash -c "'$bin' bench rendr '$tmp/c.lbc.h5' 2> '$tmp/kind.err'; [ \$? -eq 1 ] && grep -q \"unknown kind 'rendr' of bench; did you mean 'render'? (tubes, voxels, embree, bake, render\" '$tmp/kind.err' && { '$bin' bench 2> '$tmp/kind.err'; [ \$? -eq 1 ]; } && grep -q 'bench needs a kind: tubes, voxels' '$tmp/kind.err' && '$bin' bench --help | grep -q 'Usage: linebake bench'"
check "render --radius past the cached tubes' draws past the framed box: embree's capsules equal tiles' (embree's rays had been cut at the clip planes fitted to the cached radius: 10 dB, or a blank image)" bash -c "printf 'line_id,x,y,z,v\n0,0,0,0,1\n0,1,0,0,2\n' > '$tmp/seg.csv' && '$bin' bake '$tmp/seg.csv' -o '$tmp/seg.lbc.h5' --radius 0.03 > /dev/null 2>&1 && for r in 0.6 0.8; do '$bin' render '$tmp/seg.lbc.h5' --technique embree --embree-geometry capsules --radius \$r --tf opaque --size 64x64 -o '$tmp/seg-e.png' 2> /dev/null && '$bin' render '$tmp/seg.lbc.h5' --technique tiles --radius \$r --tf opaque --size 64x64 -o '$tmp/seg-t.png' 2> /dev/null && '$bin' compare '$tmp/seg-e.png' '$tmp/seg-t.png' --json | python3 -c 'import json,sys; sys.exit(0 if json.load(sys.stdin)[\"psnr_db\"] >= 50 else 1)' || exit 1; done"
check "LINEBAKE_PROGRESS=always draws the progress bar on a stderr that is no terminal (mpirun's ranks: they cannot tell), and none without it" bash -c "LINEBAKE_PROGRESS=always '$bin' convert 'synth:aneurysm?scale=0.01' -o '$tmp/progress.vtp' 2> '$tmp/progress.err' && grep -qa 'converting .*100.0%' '$tmp/progress.err' && [ \$(tr -cd '\\033' < '$tmp/progress.err' | wc -c) -gt 0 ] && '$bin' convert 'synth:aneurysm?scale=0.01' -o '$tmp/progress.vtp' 2> '$tmp/progress.err' && [ \$(tr -cd '\\033\\r' < '$tmp/progress.err' | wc -c) -eq 0 ]"
check "render --png-bits with a .pfm is exit 1 (it had been taken); tiles' unknown --attribute is exit 1 listing the names, as embree's (it had been exit 4 naming none); bench's tiles-triangles on a cache without tubes is skipped like ll (it had failed)" bash -c "'$bin' render '$tmp/c.lbc.h5' --size 16x16 -o '$tmp/bits.pfm' --png-bits 16 2> '$tmp/bits.err'; [ \$? -eq 1 ] && grep -q -- '--png-bits: read only with a .png image' '$tmp/bits.err' && [ ! -e '$tmp/bits.pfm' ] && { '$bin' render '$tmp/c.lbc.h5' --technique tiles --attribute nothere --size 16x16 -o '$tmp/attr.png' 2> '$tmp/attr.err'; [ \$? -eq 1 ]; } && grep -q -- \"--attribute: no vertex attribute named 'nothere' in these lines (\" '$tmp/attr.err' && '$bin' bake '$tmp/c.binlines' -o '$tmp/novox.lbc.h5' --assets voxels > /dev/null 2>&1 && '$bin' bench render '$tmp/novox.lbc.h5' --techniques tiles-triangles --size 16x16 --frames 1 --json 2> /dev/null | python3 -c 'import json,sys; rows=[r for run in json.load(sys.stdin)[\"runs\"] for r in run[\"rows\"] if r[\"technique\"]==\"tiles-triangles\"]; sys.exit(0 if rows and \"the cache has no tubes\" in rows[0].get(\"skipped\",\"\") else 1)'"
check "bench bake refuses an -o that exists (exit 3, the file kept, even when the options are refused too); a run's cache is removed after it, and after an interrupted run" bash -c "mkdir -p '$tmp/bbo' && cd '$tmp/bbo' && echo notes > notes.txt && for extra in '--assets nope' '--repeat 1'; do '$bin' bench bake '$tmp/c.binlines' \$extra -o notes.txt 2> o.err; [ \$? -eq 3 ] && grep -q 'notes.txt: exists: bench bake bakes a new cache there on every run' o.err && [ \"\$(cat notes.txt)\" = notes ] || exit 1; done && '$bin' bench bake '$tmp/c.binlines' --repeat 1 -o fresh.lbc.h5 > /dev/null && [ ! -e fresh.lbc.h5 ] && { timeout -s INT 1 '$bin' bench bake '$tmp/c.binlines' --repeat 50 -o int.lbc.h5 > /dev/null 2>&1; [ ! -e int.lbc.h5 ] && [ \"\$(ls)\" = \"notes.txt
o.err\" ]; }"
check "compare: an ancillary PNG chunk declaring 2 GiB is skipped unread (libpng had allocated it: 2 GB resident for a 43-byte file); palette and 1-bit PNGs compare (they were refused against their expanded rows); an RGBA PNG compares by its colours with a warning (it had been silent)" /usr/bin/python3 -c "
import resource, struct, subprocess, zlib
def chunk(kind, data):
    return struct.pack('>I', len(data)) + kind + data + struct.pack('>I', zlib.crc32(kind + data))
def png(name, width, height, depth, kind, rows, extra=b''):
    open('$tmp/' + name, 'wb').write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', width, height, depth, kind, 0, 0, 0)) + extra + chunk(b'IDAT', zlib.compress(rows, 9)) + chunk(b'IEND', b''))
header = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', 16, 12, 8, 2, 0, 0, 0))
open('$tmp/huge_text.png', 'wb').write(header + struct.pack('>I', 0x7fffffff) + b'tEXtab')
png('small.png', 16, 12, 8, 2, b''.join(b'\0' + bytes(48) for _ in range(12)))
r = subprocess.run(['$bin', 'compare', '$tmp/huge_text.png', '$tmp/small.png'], capture_output=True, text=True)
assert r.returncode == 2 and 'huge_text.png: byte offset' in r.stderr, r
assert resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss < 200000, resource.getrusage(resource.RUSAGE_CHILDREN)
png('palette.png', 1000, 1000, 8, 3, b''.join(b'\0' + bytes(1000) for _ in range(1000)), chunk(b'PLTE', bytes(768)))
png('bits.png', 1000, 1000, 1, 0, b''.join(b'\0' + bytes(125) for _ in range(1000)))
for name in ('palette.png', 'bits.png'):
    r = subprocess.run(['$bin', 'compare', '$tmp/' + name, '$tmp/' + name], capture_output=True, text=True)
    assert r.returncode == 0 and '60.0000 dB' in r.stdout and 'alpha' not in r.stderr, r
# An RGBA image compares by its colours, and says so (it had been silent).
png('rgba.png', 16, 12, 8, 6, b''.join(b'\0' + bytes(64) for _ in range(12)))
r = subprocess.run(['$bin', 'compare', '$tmp/rgba.png', '$tmp/small.png'], capture_output=True, text=True)
assert r.returncode == 0 and '60.0000 dB' in r.stdout and r.stderr.count('alpha channel') == 1 and 'rgba.png: its alpha channel (or tRNS transparency) is dropped' in r.stderr, r
"
check "compare: a PFM header ending in CRLF reads the pixels where they are (they were read a byte off: 2.7 dB against the same pixels); bytes after the pixels, or 'PF4', are exit 2" /usr/bin/python3 -c "
import struct, subprocess
pixels = struct.pack('<576f', *[0.5] * 576)
for name, data in (('lf', b'PF\n16 12\n-1.0\n' + pixels), ('crlf', b'PF\r\n16 12\r\n-1.0\r\n' + pixels), ('junk', b'PF\n16 12\n-1.0\n' + pixels + b'junk'), ('pf4', b'PF4\n16 12\n-1.0\n' + pixels)):
    open('$tmp/' + name + '.pfm', 'wb').write(data)
r = subprocess.run(['$bin', 'compare', '$tmp/crlf.pfm', '$tmp/lf.pfm'], capture_output=True, text=True)
assert r.returncode == 0 and '60.0000 dB' in r.stdout, r
r = subprocess.run(['$bin', 'compare', '$tmp/junk.pfm', '$tmp/lf.pfm'], capture_output=True, text=True)
assert r.returncode == 2 and 'junk.pfm: byte offset 2318: 4 bytes after the pixel data' in r.stderr, r
r = subprocess.run(['$bin', 'compare', '$tmp/pf4.pfm', '$tmp/lf.pfm'], capture_output=True, text=True)
assert r.returncode == 2 and 'pf4.pfm: byte offset 0: not a PFM file' in r.stderr, r
"
check "a FIFO as input is exit 2 at once, naming it (commands had waited in open() for a writer, a signal restarting the wait)" bash -c "rm -f '$tmp/pipe.pfm' && mkfifo '$tmp/pipe.pfm' && for cmd in 'depth-complexity' 'compare' 'info'; do extra=''; [ \$cmd = compare ] && extra='$tmp/pipe.pfm'; timeout -k 5 20 '$bin' \$cmd '$tmp/pipe.pfm' \$extra 2> '$tmp/pipe.err'; [ \$? -eq 2 ] && grep -q 'pipe.pfm: is a FIFO (a pipe), not a file' '$tmp/pipe.err' || exit 1; done"
check_budget "synth to .binlines under a budget below what it holds is exit 4, nothing written (it had ignored the budget, 52 MB resident under 20M); under 64M its batches fit, the same bytes as unlimited" bash -c "'$bin' synth aneurysm --scale 0.05 -o '$tmp/sb.binlines' --memory-budget 20M 2> '$tmp/sb.err'; [ \$? -eq 4 ] && grep -q \"sb.binlines: the process's resident memory reached\" '$tmp/sb.err' && [ ! -e '$tmp/sb.binlines' ] && '$bin' synth aneurysm --scale 0.05 -o '$tmp/sb.binlines' --memory-budget 64M 2> /dev/null && '$bin' synth aneurysm --scale 0.05 -o '$tmp/sb2.binlines' --memory-budget unlimited 2> /dev/null && cmp '$tmp/sb.binlines' '$tmp/sb2.binlines'"
check "a synth: source giving a parameter twice is exit 2 naming it (the last one had been taken); a .binlines attribute name holding a NUL is exit 2 at its byte (it had been cut short)" bash -c "'$bin' info 'synth:aneurysm?scale=0.01&scale=2' 2> '$tmp/twice.err'; [ \$? -eq 2 ] && grep -q 'scale: given twice; give it once' '$tmp/twice.err' && /usr/bin/python3 -c \"
import struct, sys
name = b'sp\\0eed'
open(sys.argv[1], 'wb').write(struct.pack('<IIII', 2, 1, 1, len(name)) + name + struct.pack('<I6f2f', 2, 0, 0, 0, 1, 1, 1, 0, 1))
\" '$tmp/nul.binlines' && { '$bin' info '$tmp/nul.binlines' 2> '$tmp/nul.err'; [ \$? -eq 2 ]; } && grep -q 'nul.binlines: byte offset 18: attribute name holds a NUL byte' '$tmp/nul.err'"
check_budget "bench tubes --repeat 10 under 40M peaks within it (memcpy's buffers had been sized from the budget's start: 52 MB)" /usr/bin/python3 -c "
import os, subprocess
subprocess.run(['$bin', 'synth', 'aneurysm', '--scale', '0.01', '-o', '$tmp/tubes_a.binlines'], check=True, capture_output=True)
bench = subprocess.Popen(['$bin', 'bench', 'tubes', '$tmp/tubes_a.binlines', '--memory-budget', '40M', '--repeat', '10'], stdout=subprocess.DEVNULL)
_, status, usage = os.wait4(bench.pid, 0)  # this child's own peak
assert os.waitstatus_to_exitcode(status) == 0 and usage.ru_maxrss <= 40 * 1024, (status, usage.ru_maxrss)
"
check "a file name that is not UTF-8 bakes; JSON records it with U+FFFD" /usr/bin/python3 -c "
import json, os, shutil, subprocess
name = os.path.join(b'$tmp', b'n\\xff.binlines')
shutil.copy('$tmp/c.binlines', name)
subprocess.run([b'$bin', b'bake', name, b'-o', b'$tmp/nonutf8.lbc.h5'], check=True, capture_output=True)
info = json.loads(subprocess.run(['$bin', 'info', '$tmp/nonutf8.lbc.h5', '--json'], check=True, capture_output=True).stdout)
assert info['metadata']['source'].endswith('n\\ufffd.binlines'), info['metadata']
os.remove(name); os.remove('$tmp/nonutf8.lbc.h5')"
check "a bad pipeline names the file and the entry" bash -c "echo '{\"datasets\": [], \"techniques\": [\"reference\"]}' > '$tmp/bad.json'; '$bin' run '$tmp/bad.json' 2> '$tmp/bad.err'; [ \$? -eq 2 ] && grep -q 'bad.json: datasets' '$tmp/bad.err'"
check "no temporary files left after bake/export" bash -c "! ls '$tmp' | grep -q tmp-"

# The streamed bake: the same datasets for any budget, stock HDF5 reads every codec, budgets
# too small refused, spill files gone after Ctrl-C
hashes() { h5dump -A "$1" | grep -A12 'ATTRIBUTE "xxh3_128_blocks"' | grep '(0):'; }
export -f hashes
check_budget "bake with a small budget" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/small.lbc.h5' --assets tubes,voxels,embree --grid 96 --chunk-bytes 1000000 --memory-budget 100M > /dev/null 2> '$tmp/small.err' && grep -q 'stage build' '$tmp/small.err'"
check "bake unlimited" "$bin" bake "$tmp/c.binlines" -o "$tmp/big.lbc.h5" --assets tubes,voxels,embree --grid 96 --chunk-bytes 1000000 --memory-budget unlimited
check_budget "every dataset the same bytes for both budgets" bash -c "[ \$(hashes '$tmp/small.lbc.h5' | wc -l) -gt 20 ] && diff <(hashes '$tmp/small.lbc.h5') <(hashes '$tmp/big.lbc.h5')"
export HDF5_PLUGIN_PATH=/usr/lib/x86_64-linux-gnu/hdf5/serial/plugins
check "bake uncompressed" "$bin" bake "$tmp/c.binlines" -o "$tmp/none.lbc.h5" --compression none
h5dump -d /assets/tubes/chunk_000000/positions -s 1000,0 -c 4,3 "$tmp/none.lbc.h5" | grep -A3 'DATA {' > "$tmp/none.dump"
for codec in lz4 deflate blosc-zstd; do
  check "bake $codec" "$bin" bake "$tmp/c.binlines" -o "$tmp/$codec.lbc.h5" --compression "$codec"
  check "h5dump reads a $codec chunk as written (HDF5's own filters)" bash -c "h5dump -d /assets/tubes/chunk_000000/positions -s 1000,0 -c 4,3 '$tmp/$codec.lbc.h5' | grep -A3 'DATA {' | diff - '$tmp/none.dump' && h5dump -p -d /lines/points '$tmp/$codec.lbc.h5' | grep -q FLETCHER32"
done
unset HDF5_PLUGIN_PATH
# Under ulimit -v (AddressSanitizer cannot start there: check_budget skips these). The default
# budget follows the limit where it is the smallest: checked where the machine's and the cgroups'
# own would be more than 1.91 GiB (the budget a bake reports without the limit).
default_budget=$("$bin" bake "$tmp/c.binlines" -o "$tmp/ulimit.lbc.h5" 2>&1 | grep -o 'budget [0-9.]* [GT]iB' | head -1)
rm -f "$tmp/ulimit.lbc.h5"
if [ -n "$default_budget" ] && awk -v b="$default_budget" 'BEGIN { split(b, f, " "); exit !(f[3] == "TiB" || f[2] > 1.91) }'; then
  check_budget "under ulimit -v the default budget is half of the address-space limit (4,000,000 KiB: 1.91 GiB)" bash -c "ulimit -v 4000000; '$bin' bake '$tmp/c.binlines' -o '$tmp/ulimit.lbc.h5' 2>&1 | grep -q 'budget 1.91 GiB' && rm '$tmp/ulimit.lbc.h5'"
fi
# One CPU: thread stacks and malloc arenas take address space too (a thread that cannot start
# would fail otherwise).
check_budget "an allocation past ulimit -v under an unlimited budget: exit 4, said as out of memory" bash -c "ulimit -v 200000; taskset -c 0 '$bin' bench tubes '$tmp/c.binlines' --memory-budget unlimited --repeat 1 > /dev/null 2> '$tmp/oom.err'; [ \$? -eq 4 ] && grep -q '^linebake: error: out of memory: an allocation failed' '$tmp/oom.err'"
# lavapipe (Mesa 22.3) frees twice when vkCreateDevice runs out of address space, and the
# process aborts: refused before, with the figures (its 2 worker threads: 192 + 2 x 128 MiB).
check_budget "lavapipe's device past what ulimit -v leaves: exit 4 before vkCreateDevice, no image" bash -c "ulimit -v 450000; LP_NUM_THREADS=2 '$bin' render '$tmp/c.lbc.h5' --technique ll --size 24x16 -o '$tmp/as.png' 2> '$tmp/as.err'; [ \$? -eq 4 ] && grep -q 'lavapipe.s device needs about 448.00 MiB of address space (2 worker threads' '$tmp/as.err' && [ ! -e '$tmp/as.png' ]"
check "a budget below what the process holds: exit 4, nothing left" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/tiny.lbc.h5' --memory-budget 20M 2> '$tmp/tiny.err'; [ \$? -eq 4 ] && grep -q 'memory budget of 20.00 MiB' '$tmp/tiny.err' && [ ! -e '$tmp/tiny.lbc.h5' ] && ! ls '$tmp' | grep -q tmp-"
check_budget "bench bake --json" python3 -c "
import json, subprocess
j = json.loads(subprocess.run(['$bin', 'bench', 'bake', '--input', '$tmp/c.binlines', '-o', '$tmp/bench.lbc.h5', '--repeat', '1', '--memory-budget', '128M', '--json'], check=True, capture_output=True, text=True).stdout)
assert j['segments'] == 495000 and j['memory_budget_bytes'] == 128 << 20, j
assert [s['stage'] for s in j['stages']][:3] == ['read', 'lines', 'build'], j['stages']
assert 0 < j['peak_rss_bytes'] <= 128 << 20 and j['bytes_written'] > 0 and j['memcpy_GBps'] > 0, j
import os; assert not os.path.exists('$tmp/bench.lbc.h5')"
check "bench bake without -o: <input name>.bench.lbc.h5 in the working directory, kept with --keep" bash -c "mkdir -p '$tmp/bbd' && cd '$tmp/bbd' && '$bin' bench bake '$tmp/c.binlines' --repeat 1 --keep --json > /dev/null && [ \"\$(ls)\" = c.bench.lbc.h5 ]"
check "writes past ulimit -f (SIGXFSZ not trapped by the caller): export and convert exit 3 with 'File too large', nothing left (the signal had ended them, exit 153, temporaries left)" bash -c "mkdir -p '$tmp/xfsz' && cd '$tmp/xfsz' && bash -c \"ulimit -f 100; '$bin' export '$tmp/c.lbc.h5' -o x.glb 2> x.err; echo \\\$? > x.rc; '$bin' convert '$tmp/c.lbc.h5' -o y.vtp 2> y.err; echo \\\$? > y.rc\"; [ \"\$(cat x.rc)\" = 3 ] && [ \"\$(cat y.rc)\" = 3 ] && grep -q 'File too large' x.err && grep -q 'File too large' y.err && [ \"\$(ls -A)\" = \"\$(printf 'x.err\\nx.rc\\ny.err\\ny.rc')\" ]"
check "a bake that adds to a cache and runs out of file size (ulimit -f) while copying its reused groups: exit 3, the cache as it was, no lock or temporary file (HDF5's H5Ocopy had crashed, exit 139)" bash -c "mkdir -p '$tmp/fsize' && cd '$tmp/fsize' && '$bin' bake 'synth:convection?scale=0.01' -o f.lbc.h5 > /dev/null 2>&1 && before=\$(md5sum < f.lbc.h5) && bash -c \"ulimit -f 300; exec '$bin' bake f.lbc.h5 --assets tubes,voxels --no-space-check\" > /dev/null 2> f.err; rc=\$?; [ \$rc -eq 3 ] && grep -q 'File too large' f.err && [ \"\$(md5sum < f.lbc.h5)\" = \"\$before\" ] && [ \"\$(ls -A)\" = \"\$(printf 'f.err\\nf.lbc.h5')\" ]"
check "Ctrl-C during a bake: exit 130, no cache, no spill or temporary file" bash -c "
'$bin' synth clouds --scale 0.1 -o '$tmp/k.binlines' 2> /dev/null
'$bin' bake '$tmp/k.binlines' -o '$tmp/k.lbc.h5' --assets tubes,voxels --grid 128 --memory-budget $(incidental_budget 128M) 2> '$tmp/int.err' > /dev/null & pid=\$!
for i in \$(seq 200); do ls '$tmp' | grep -q 'k.lbc.h5.*tmp-' && break; sleep 0.02; done
sleep 0.3; kill -INT \$pid; wait \$pid; rc=\$?
[ \$rc -eq 130 ] && grep -q 'interrupted by SIGINT' '$tmp/int.err' && [ ! -e '$tmp/k.lbc.h5' ] && ! ls '$tmp' | grep -q tmp-"
check "Ctrl-C during a Draco export (about 4.7 s on the development VM): exit 130, no output, no temporary file" bash -c "
'$bin' export '$tmp/c.lbc.h5' -o '$tmp/kx.glb' --draco --draco-speed 0 2> '$tmp/xint.err' > /dev/null & pid=\$!
sleep 0.7; kill -INT \$pid; wait \$pid; rc=\$?
[ \$rc -eq 130 ] && grep -q 'interrupted by SIGINT' '$tmp/xint.err' && [ ! -e '$tmp/kx.glb' ] && ! ls '$tmp' | grep -q tmp-"
check "SIGTERM during a render's only frame (about 1.6 s at 1600x1200 on the development VM): exit 143 with no image, or, where the frame was done first, exit 143 naming the image written whole (it had exited 0)" bash -c "
'$bin' render '$tmp/c.lbc.h5' --technique embree --size 1600x1200 -o '$tmp/term.png' 2> '$tmp/term.err' > /dev/null & pid=\$!
sleep 1; kill -TERM \$pid; wait \$pid; rc=\$?
[ \$rc -eq 143 ] && ! ls '$tmp' | grep -q 'term.png.*tmp-' && { { [ ! -e '$tmp/term.png' ] && grep -q '^linebake: interrupted by SIGTERM; its temporary files are removed' '$tmp/term.err'; } || grep -qF 'interrupted by SIGTERM as the command finished: $tmp/term.png was written whole' '$tmp/term.err'; }"

# One contract (docs/cli.md): catalogues, help, in-place bakes, what is dropped, what stays on a terminal
check "techniques --json lists every technique render accepts" python3 -c "
import json, re, subprocess
rows = json.loads(subprocess.run(['$bin', 'techniques', '--json'], capture_output=True, text=True, check=True).stdout)
names = [r['name'] for r in rows]
help = subprocess.run(['$bin', 'render', '--help'], capture_output=True, text=True).stdout
accepted = [n.strip() for n in re.search(r'--technique TEXT:\{([^}]*)\}', help).group(1).split(',')]
assert names == accepted, (names, accepted)
rtx = [r for r in rows if r['name'] == 'rtx'][0]
assert not rtx['available'] and 'ray tracing' in rtx['unavailable_reason'], rtx
assert all(r['available'] for r in rows if r['name'] != 'rtx'), rows
"
check "formats --json: every format convert can write is marked writable" python3 -c "
import json, subprocess
rows = {r['name']: r for r in json.loads(subprocess.run(['$bin', 'formats', '--json'], capture_output=True, text=True, check=True).stdout)}
for name in ('obj', 'vtk', 'vtp', 'hdf5', 'csv', 'binlines'):
    assert rows[name]['write'], name
for name in ('netcdf', 'trk', 'tck'):
    assert not rows[name]['write'], name
assert rows['hdf5']['metadata'] and rows['vtk']['line_attributes'] and not rows['csv']['line_attributes']
# What the read-only formats' readers keep: TrackVis properties as line attributes, header keys
# of trk, tck and NetCDF as metadata (the table said no for all of them).
assert rows['trk']['line_attributes'] and all(rows[n]['metadata'] for n in ('trk', 'tck', 'netcdf')), rows
"
check "help CMD is CMD --help; version names the version" bash -c "[ \"\$('$bin' help render)\" = \"\$('$bin' render --help)\" ] && [ \"\$('$bin' help bench voxels)\" = \"\$('$bin' bench voxels --help)\" ] && '$bin' version | grep -q '^linebake [0-9]*\.[0-9]*\.[0-9]* (HDF5 '"
check "bake CACHE adds assets in place, reusing its /lines" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/ip.lbc.h5' >/dev/null 2>&1 && '$bin' bake '$tmp/ip.lbc.h5' --assets tubes,voxels --grid 32 2> '$tmp/ip.err' >/dev/null && grep -q 'lines: up to date, reused' '$tmp/ip.err' && grep -q 'voxels: built' '$tmp/ip.err' && '$bin' report '$tmp/ip.lbc.h5' --json | grep -q '\"quantization\": 32' && ! ls '$tmp' | grep -q 'ip.lbc.lbc'"
check "an in-place bake without --compression keeps the cache's codec and level, rebuilding nothing for it" bash -c "'$bin' bake '$tmp/c.binlines' -o '$tmp/nc.lbc.h5' --compression deflate --compression-level 3 >/dev/null 2>&1 && '$bin' bake '$tmp/nc.lbc.h5' --assets tubes,voxels --grid 8 2> '$tmp/nc.err' >/dev/null && tr '\\n' ' ' < '$tmp/nc.err' | grep -q 'lines: up to date, reused linebake: tubes: up to date, reused linebake: voxels: built' && /usr/bin/python3 -c \"import h5py, json, sys; f = h5py.File(sys.argv[1], 'r'); p = [json.loads(f[g].attrs['provenance']) for g in ('/lines', '/assets/tubes', '/assets/voxels')]; sys.exit(0 if all(q['compression'] == 'deflate' and q['compression_level'] == 3 for q in p) else 1)\" '$tmp/nc.lbc.h5' && '$bin' bake '$tmp/nc.lbc.h5' --compression lz4 2> '$tmp/nc2.err' >/dev/null && grep -q 'lines: built' '$tmp/nc2.err'"
check "baking other lines into a cache names the assets it drops" bash -c "'$bin' synth aneurysm --scale 0.002 -o '$tmp/small.binlines' 2>/dev/null && '$bin' bake '$tmp/small.binlines' -o '$tmp/ip.lbc.h5' 2> '$tmp/drop.err' >/dev/null && grep -q \"dropped the cache's voxels: it was built from other lines\" '$tmp/drop.err'"
check "convert names what the format cannot hold; --strict refuses it" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/ll.csv' --derive line_length 2> '$tmp/lost.err' && grep -q 'linebake: warning: .*ll.csv: csv cannot hold line attribute line_length' '$tmp/lost.err' && '$bin' convert '$tmp/c.binlines' -o '$tmp/ll2.csv' --derive line_length --strict 2>/dev/null; [ \$? -eq 4 ] && [ ! -e '$tmp/ll2.csv' ]"
check "--derive of an existing attribute replaces it, once" bash -c "'$bin' convert '$tmp/c.binlines' -o '$tmp/cv.h5' --derive curvature 2> '$tmp/cv.err' && grep -q 'replaces the input' '$tmp/cv.err' && [ \$(h5ls '$tmp/cv.h5/attributes' | grep -c curvature) -eq 1 ] && '$bin' bake '$tmp/cv.h5' -o '$tmp/cv.lbc.h5' >/dev/null 2>&1"
check "on a terminal the result stays after the progress bar" bash -c "script -qec \"'$bin' render '$tmp/t.lbc.h5' --size 24x16 -o '$tmp/tty.png'\" /dev/null | tr '\r' '\n' | grep -q 'linebake: embree: 1 frame in .* s, [^:]*: .*tty.png' && script -qec \"'$bin' export '$tmp/t.lbc.h5' -o '$tmp/tty.glb'\" /dev/null | grep -q 'linebake: wrote .*tty.glb ([0-9.]* [KM]iB) in '"

check "VTK's own readers read linebake's metadata (vtp, vtk binary and ascii)" bash -c "'$bin' synth aneurysm --scale 0.002 -o '$tmp/meta.h5' 2>/dev/null && '$bin' convert '$tmp/meta.h5' -o '$tmp/meta.vtp' 2>/dev/null && '$bin' convert '$tmp/meta.h5' -o '$tmp/meta.vtk' 2>/dev/null && '$bin' convert '$tmp/meta.h5' -o '$tmp/meta_a.vtk' --ascii 2>/dev/null && /usr/bin/python3 -c \"
import vtk
for f, R in (('meta.vtp', vtk.vtkXMLPolyDataReader), ('meta.vtk', vtk.vtkPolyDataReader), ('meta_a.vtk', vtk.vtkPolyDataReader)):
    r = R(); r.SetFileName('$tmp/' + f); r.Update(); d = r.GetOutput().GetFieldData()
    m = {d.GetAbstractArray(i).GetName(): d.GetAbstractArray(i).GetValue(0) for i in range(d.GetNumberOfArrays())}
    assert m['synth.scale'] == '0.002000' and m['synth.description'].startswith('streamlines in a vessel'), (f, m)
    assert r.GetOutput().GetNumberOfLines() > 0, f
\""

# HDF5 line files as h5py writes them (the probe of 2026-11-29): a filter this HDF5 lacks (h5py's
# own LZF) named; float offsets and negative lengths refused naming the value (HDF5's conversion
# took the floor and 0, silently); a group under /attributes and a bool (enum) array named as
# such; an empty set as empty offsets read; numeric root attributes kept as metadata text.
check "HDF5 line files from h5py: conventions read, what cannot be read named" bash -c "
set -e
cd '$tmp'
/usr/bin/python3 -c \"
import h5py, numpy as np
points = np.arange(60, dtype='f4').reshape(20, 3)
def line_file(path):
    f = h5py.File(path, 'w'); f['points'] = points; return f
f = line_file('lzf.h5'); f.create_dataset('line_offsets', data=np.array([0, 5, 20], 'u8'), compression='lzf'); f.close()
f = line_file('float_offsets.h5'); f['line_offsets'] = np.array([0, 5.5, 8, 16, 20]); f.close()
f = line_file('negative.h5'); f['line_lengths'] = np.array([10, -3, 13], 'i4'); f.close()
f = line_file('subgroup.h5'); f['line_offsets'] = np.array([0, 5, 20], 'u8'); f.create_group('attributes/sub'); f.close()
f = line_file('bool.h5'); f['line_offsets'] = np.array([0, 5, 20], 'u8'); f['attributes/flag'] = np.ones(20, bool); f.close()
f = h5py.File('empty.h5', 'w'); f['points'] = np.zeros((0, 3), 'f4'); f['line_offsets'] = np.zeros(0, 'u8'); f.close()
f = line_file('attrs.h5'); f['line_offsets'] = np.array([0, 5, 20], 'i8')
f.attrs['dt'] = 0.1; f.attrs['n'] = np.int32(-7); f.attrs['v'] = np.array([1, 2, 3], 'u2'); f.close()
\"
refused() { ! '$bin' info \"\$1\" > /dev/null 2> err.txt; grep -qF \"\$1: \$2\" err.txt || { cat err.txt; exit 1; }; }
refused lzf.h5 'dataset /line_offsets: compressed with HDF5 filter 32000 (lzf), which this HDF5 cannot decode'
refused float_offsets.h5 'dataset /line_offsets: holds floating-point values'
refused negative.h5 'dataset /line_lengths: value -3 at index 1 is negative'
refused subgroup.h5 'group /attributes/sub: a group where a dataset belongs'
refused bool.h5 'dataset /attributes/flag: an enumeration'
'$bin' info empty.h5 --json | /usr/bin/python3 -c 'import json, sys; j = json.load(sys.stdin); assert (j[\"lines\"], j[\"points\"]) == (0, 0), j'
'$bin' info attrs.h5 --json | /usr/bin/python3 -c 'import json, sys; m = json.load(sys.stdin)[\"metadata\"]; assert (m[\"dt\"], m[\"n\"], m[\"v\"]) == (\"0.1\", \"-7\", \"1 2 3\"), m'
"

# A cache read as lines decodes its own chunks: no HDF5 filter plugin is needed (the filter
# check for other tools' files had refused an LZ4 cache where none could be loaded).
check "a cache reads as lines without HDF5's filter plugins" bash -c "HDF5_PLUGIN_PRELOAD=:: '$bin' info '$tmp/c.lbc.h5' --json | /usr/bin/python3 -c 'import json, sys; assert json.load(sys.stdin)[\"lines\"] > 0'"
check "review fixes: array root attributes, VTK's multi-value binary strings, one-tile tiles, --help CMD, in-place through a link" bash -c "
set -e
'$bin' convert '$tmp/c.binlines' -o '$tmp/arr.h5' 2>/dev/null
/usr/bin/python3 -c \"import h5py, numpy as np; f = h5py.File('$tmp/arr.h5', 'a'); f.attrs['tags'] = np.array([b'ab', b'cd']); f.attrs['units'] = np.bytes_('m')\"
'$bin' info '$tmp/arr.h5' --json | grep -q '\"units\": \"m\"'
/usr/bin/python3 -c \"
import vtk
pd = vtk.vtkPolyData(); pts = vtk.vtkPoints(); pts.InsertNextPoint(0, 0, 0); pts.InsertNextPoint(1, 0, 0); pd.SetPoints(pts)
ca = vtk.vtkCellArray(); ca.InsertNextCell(2); ca.InsertCellPoint(0); ca.InsertCellPoint(1); pd.SetLines(ca)
for name, values in (('two', ['first value', 'second']), ('one', ['kept'])):
    a = vtk.vtkStringArray(); a.SetName(name)
    for v in values: a.InsertNextValue(v)
    pd.GetFieldData().AddArray(a)
w = vtk.vtkPolyDataWriter(); w.SetFileName('$tmp/strings.vtk'); w.SetInputData(pd); w.SetFileTypeToBinary(); w.SetFileVersion(42); w.Write()
\"
'$bin' info '$tmp/strings.vtk' --json | grep -q '\"one\": \"kept\"'
'$bin' render '$tmp/t.lbc.h5' --technique tiles --size 16x16 -o '$tmp/one.png' 2>/dev/null
'$bin' render '$tmp/t.lbc.h5' --embree-geometry capsules --size 16x16 -o '$tmp/one_e.png' 2>/dev/null
'$bin' compare '$tmp/one.png' '$tmp/one_e.png' --json | python3 -c 'import json,sys; assert json.load(sys.stdin)[\"psnr_db\"] >= 50'
'$bin' --help bake | grep -q 'Usage: linebake bake'
ln -sf '$tmp/t.lbc.h5' '$tmp/link.lbc.h5'
rc=0; '$bin' bake '$tmp/link.lbc.h5' --assets tubes,voxels 2> '$tmp/link.err' || rc=\$?
[ \$rc -eq 3 ] && grep -q 'is a link' '$tmp/link.err'
"

check "second review fixes: in-place /lines keep their identity, the attribute check on reused lines, bench options before the step, control characters in VTP names, an asset without provenance" bash -c "
set -e
'$bin' bake '$tmp/c.binlines' -o '$tmp/keep.lbc.h5' --assets tubes,voxels --grid 16 >/dev/null 2>&1
prov() { /usr/bin/python3 -c \"import h5py, json, sys; p = json.loads(h5py.File(sys.argv[1], 'r')['/lines'].attrs['provenance']); print(p['key'], p['input_hash'], p['parameters']['source'], p['compression'])\" \"\$1\"; }
before=\$(prov '$tmp/keep.lbc.h5')
'$bin' bake '$tmp/keep.lbc.h5' --compression deflate 2> '$tmp/keep.err' >/dev/null
grep -q 'lines: built' '$tmp/keep.err'
after=\$(prov '$tmp/keep.lbc.h5')
[ \"\${before% *}\" = \"\${after% *}\" ] && [ \"\${after##* }\" = deflate ] && case \"\$after\" in *c.binlines*) ;; *) exit 1 ;; esac
rc=0; '$bin' bake '$tmp/keep.lbc.h5' --assets embree --attribute nosuch 2> '$tmp/keep.err' || rc=\$?
[ \$rc -eq 1 ] && grep -q \"no vertex attribute named 'nosuch'\" '$tmp/keep.err'
'$bin' bench --input '$tmp/c.binlines' --repeat 1 tubes --json 2> '$tmp/bench.err' | grep -q '\"input\"'
grep -q 'bench --input is deprecated' '$tmp/bench.err'
grep -q 'bench options before the step (--input) are deprecated; give them after it: linebake bench tubes' '$tmp/bench.err'
'$bin' convert '$tmp/c.binlines' -o '$tmp/ctl.h5' 2>/dev/null
/usr/bin/python3 -c \"import h5py; f = h5py.File('$tmp/ctl.h5', 'a'); f.attrs['bell\x07key'] = 'v'; f.attrs['tab\tkey'] = 'w'\"
'$bin' convert '$tmp/ctl.h5' -o '$tmp/ctl.vtp' 2>/dev/null
/usr/bin/python3 -c \"
import vtk
r = vtk.vtkXMLPolyDataReader(); r.SetFileName('$tmp/ctl.vtp'); r.Update(); d = r.GetOutput().GetFieldData()
names = {d.GetAbstractArray(i).GetName() for i in range(d.GetNumberOfArrays())}
assert 'bell\ufffdkey' in names and 'tab\tkey' in names, names
assert r.GetOutput().GetNumberOfLines() > 0
\"
/usr/bin/python3 -c \"import h5py; del h5py.File('$tmp/keep.lbc.h5', 'a')['/assets/voxels'].attrs['provenance']\"
'$bin' bake '$tmp/small.binlines' -o '$tmp/keep.lbc.h5' 2> '$tmp/keep.err' >/dev/null
grep -q \"dropped the cache's voxels: it has no provenance\" '$tmp/keep.err'
"

corpus="$(dirname "$0")/fuzz/corpus"
check "empty is valid: nibabel-style .tck and .trk with no streamlines read as 0 lines, convert to every writable format, bake refuses with no cache" bash -c "
set -e
for f in '$corpus/tck/empty.tck' '$corpus/trk/empty.trk'; do
  '$bin' info \"\$f\" --json | /usr/bin/python3 -c 'import json, sys; j = json.load(sys.stdin); assert j[\"lines\"] == 0 and j[\"points\"] == 0, j'
done
for ext in obj binlines vtk vtp h5 csv; do
  '$bin' convert '$corpus/tck/empty.tck' -o '$tmp/empty.'\$ext 2>/dev/null
  [ \"\$('$bin' info '$tmp/empty.'\$ext --json | /usr/bin/python3 -c 'import json, sys; print(json.load(sys.stdin)[\"lines\"])')\" = 0 ]
done
/usr/bin/python3 -c \"
import vtk
for f, R in (('empty.vtp', vtk.vtkXMLPolyDataReader), ('empty.vtk', vtk.vtkPolyDataReader)):
    r = R(); r.SetFileName('$tmp/' + f); r.Update(); assert r.GetOutput().GetNumberOfLines() == 0, f
\"
rc=0; '$bin' bake '$corpus/tck/empty.tck' -o '$tmp/empty.lbc.h5' 2> '$tmp/empty.err' || rc=\$?
[ \$rc -eq 2 ] && grep -q 'has no lines: nothing to bake' '$tmp/empty.err' && [ ! -e '$tmp/empty.lbc.h5' ]
"
check "bake of lines that repair drops every one of: exit 2, says that repair dropped them (it said 'has no lines')" bash -c "printf 'v nan 0 0\\nv 1 1 1\\nl 1 2\\n' > '$tmp/nan.obj'; rc=0; '$bin' bake '$tmp/nan.obj' -o '$tmp/nan.lbc.h5' 2> '$tmp/nan.err' || rc=\$?; [ \$rc -eq 2 ] && grep -q 'has no line left once repaired (1 invalid points' '$tmp/nan.err' && [ ! -e '$tmp/nan.lbc.h5' ]"

echo "cli: $passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
