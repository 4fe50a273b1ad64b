#!/usr/bin/env bash
# Writes the fuzz targets' seed corpora into tests/fuzz/corpus/<target>/: small valid files of
# every variant the readers take, made by linebake itself from a hand-written CSV line set (three
# lines, one of a single point), by Python (TrackVis, MRtrix, the JSON and YAML inputs) and by
# ncgen (NetCDF: Lagranto, CF multidimensional, CF contiguous ragged). The committed corpus is
# this script's output plus the regression inputs the fuzzers found (named crash-*), plus files
# as other tools write them, made once with those tools (2026-11-29): python3-vtk9's writers
# (vtk9-*: METADATA blocks, component names, COLOR_SCALARS), nibabel-style TrackVis name slots
# (nibabel-*), h5py (h5py-*: signed lengths, numeric root attributes, filters), netCDF4-python
# (packed-*, ragged-reserved: CF packing, NC_STRING attributes, reserved observations), and
# spreadsheet-style CSV, OBJ vertex colours and MRtrix headers (their own names).
#   tests/fuzz/make_corpus.sh LINEBAKE        (LINEBAKE: a release build's linebake)
set -euo pipefail
bin=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
out="$here/corpus"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
seed() { mkdir -p "$out/$1" && cp "$2" "$out/$1/$3"; }
quiet() { "$@" >/dev/null 2>&1; }

# The line set: three lines, an attribute, a point repeated, one line of one point.
cat >"$tmp/lines.csv" <<'CSV'
line_id,x,y,z,speed
0,0,0,0,0.5
0,1,0,0,1.5
0,1,1,0,2.5
0,1,1,0,2.5
1,0,0,1,-1
1,0.5,0.25,1.5,1e-3
1,2,3,4,7
2,5,5,5,0
CSV
seed csv "$tmp/lines.csv" lines.csv
printf 'x,y,z\n0,0,0\n1,2,3\n' >"$tmp/bare.csv"
seed csv "$tmp/bare.csv" bare.csv
printf 'line_id,x,y,z\n' >"$tmp/empty.csv"
seed csv "$tmp/empty.csv" empty.csv
l="$tmp/lines.csv"
quiet "$bin" convert "$l" -o "$tmp/a.obj" && seed obj "$tmp/a.obj" lines.obj
printf 'v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2 3\nl -1 -3\n# comment\n' >"$tmp/b.obj"
seed obj "$tmp/b.obj" relative.obj
quiet "$bin" convert "$l" -o "$tmp/a.binlines" && seed binlines "$tmp/a.binlines" v2.binlines
quiet "$bin" convert "$l" -o "$tmp/b.binlines" --binlines-version 1 &&
  seed binlines "$tmp/b.binlines" v1.binlines
quiet "$bin" convert "$l" -o "$tmp/a.vtk" --derive line_length && seed vtk "$tmp/a.vtk" binary.vtk
quiet "$bin" convert "$l" -o "$tmp/b.vtk" --ascii --derive line_length &&
  seed vtk "$tmp/b.vtk" ascii.vtk
for enc in appended appended-base64 base64 ascii; do
  quiet "$bin" convert "$l" -o "$tmp/$enc.vtp" --vtp-encoding "$enc" --derive line_length &&
    seed vtp "$tmp/$enc.vtp" "$enc.vtp"
done
quiet "$bin" convert "$l" -o "$tmp/raw.vtp" --no-compress && seed vtp "$tmp/raw.vtp" uncompressed.vtp
quiet "$bin" convert "$l" -o "$tmp/a.h5" --derive line_length && seed hdf5 "$tmp/a.h5" lines.h5
# Far-off coordinates (UTM-like) written at an origin: float64 points in VTK and VTP, the HDF5
# file's root attribute `origin` (docs/cli.md, "Far-off coordinates").
printf 'line_id,x,y,z\n0,500000.25,5400000.5,12\n0,500001,5400001.75,12.5\n1,500002,5400000,13\n1,500003,5400002.5,13\n' \
  >"$tmp/far.csv"
seed csv "$tmp/far.csv" far-off.csv
for ext in vtk vtp h5; do
  target=$ext && [ "$ext" = h5 ] && target=hdf5
  quiet "$bin" convert "$tmp/far.csv" -o "$tmp/far.$ext" --origin auto &&
    seed "$target" "$tmp/far.$ext" "far-off.$ext"
done

# The cache: lines, tubes, voxels and Embree curves, uncompressed and LZ4.
for codec in none lz4; do
  quiet "$bin" bake "$l" -o "$tmp/$codec.lbc.h5" --assets tubes,voxels,embree --grid 4 \
    --compression "$codec" && seed cache "$tmp/$codec.lbc.h5" "$codec.lbc.h5"
done

# Images: 8- and 16-bit PNG, PFM.
quiet "$bin" render "$tmp/none.lbc.h5" --size 6x4 -o "$tmp/a.png" && seed png "$tmp/a.png" rgb8.png
quiet "$bin" render "$tmp/none.lbc.h5" --size 6x4 --png-bits 16 -o "$tmp/b.png" &&
  seed png "$tmp/b.png" rgb16.png
quiet "$bin" render "$tmp/none.lbc.h5" --size 6x4 -o "$tmp/a.pfm" && seed pfm "$tmp/a.pfm" rgb.pfm

# TrackVis and MRtrix, both byte orders, with and without streamlines (nibabel writes empty ones).
/usr/bin/python3 - "$out" <<'PY'
import math, os, struct, sys
out = sys.argv[1]
def save(target, name, data):
    os.makedirs(os.path.join(out, target), exist_ok=True)
    open(os.path.join(out, target, name), 'wb').write(data)
def trk(order, lines, scalars=1, properties=1):
    h = bytearray(1000)
    struct.pack_into(order + '6s3h3f3fh', h, 0, b'TRACK', 10, 20, 30, 1.5, 1.5, 2.0, 0, 0, 0, scalars)
    for i in range(scalars): struct.pack_into('20s', h, 38 + 20 * i, b'fa')
    struct.pack_into(order + 'h', h, 238, properties)
    for i in range(properties): struct.pack_into('20s', h, 240 + 20 * i, b'length')
    struct.pack_into(order + '16f', h, 440, *[1.0 if i % 5 == 0 else 0.0 for i in range(16)])
    struct.pack_into('4s', h, 948, b'LPS')
    struct.pack_into(order + '3i', h, 988, len(lines), 2, 1000)
    body = bytearray()
    for n, line in enumerate(lines):
        body += struct.pack(order + 'i', len(line))
        for p in line: body += struct.pack(order + '3f', *p) + struct.pack(order + 'f', 0.5) * scalars
        body += struct.pack(order + 'f', float(n)) * properties
    return bytes(h) + bytes(body)
lines = [[(1, 2, 3), (4, 5, 6)], [(0, 0, 1), (-1, 0, 1), (-2, 0, 1)]]
save('trk', 'little.trk', trk('<', lines))
save('trk', 'big.trk', trk('>', lines))
save('trk', 'empty.trk', trk('<', []))
def tck(kind, lines, finished=True):
    code = {'Float32LE': '<f', 'Float32BE': '>f', 'Float64LE': '<d', 'Float64BE': '>d'}[kind]
    text = 'mrtrix tracks\ndatatype: %s\ncount: %d\nfile: . 64\nEND\n' % (kind, len(lines))
    data = bytearray(text.ljust(64).encode())
    for line in lines:
        for p in line + [(math.nan,) * 3]: data += b''.join(struct.pack(code, v) for v in p)
    if finished: data += b''.join(struct.pack(code, math.inf) for _ in range(3))
    return bytes(data)
for kind in ('Float32LE', 'Float32BE', 'Float64LE', 'Float64BE'):
    save('tck', kind + '.tck', tck(kind, lines))
save('tck', 'empty.tck', tck('Float32LE', []))
save('tck', 'unfinished.tck', tck('Float32LE', lines, False))
PY

# NetCDF: Lagranto (classic), CF multidimensional (netCDF-4), CF contiguous ragged (classic).
if command -v ncgen >/dev/null; then
  cat >"$tmp/lagranto.cdl" <<'CDL'
netcdf lagranto {
dimensions: ensemble = 1 ; trajectory = 2 ; time = 3 ;
variables:
  double lon(ensemble, trajectory, time) ; lon:_FillValue = -999. ;
  float lat(ensemble, trajectory, time) ; float p(ensemble, trajectory, time) ;
  float T(ensemble, trajectory, time) ;
data:
  lon = 1, 2, -999, 4, 5, 6 ; lat = 45, 46, 47, 48, 49, 50 ;
  p = 900, 890, 880, 870, 860, 850 ; T = 280, 279, 278, 277, 276, 275 ;
}
CDL
  cat >"$tmp/cf.cdl" <<'CDL'
netcdf cf {
dimensions: member = 1 ; run = 1 ; trajectory = 2 ; obs = 3 ;
variables:
  double lon(member, run, trajectory, obs) ; float lat(member, run, trajectory, obs) ;
  float p(member, run, trajectory, obs) ; int QV(member, run, trajectory, obs) ;
  QV:missing_value = -1 ;
  :featureType = "trajectory" ;
data:
  lon = 1, 2, 3, 4, 5, 6 ; lat = 45, 46, 47, 48, 49, 50 ; p = 1, 2, 3, 4, 5, 6 ;
  QV = 1, -1, 3, 4, 5, 6 ;
}
CDL
  cat >"$tmp/ragged.cdl" <<'CDL'
netcdf ragged {
dimensions: trajectory = 2 ; obs = 5 ;
variables:
  int n(trajectory) ; n:sample_dimension = "obs" ;
  double a(obs) ; a:axis = "X" ; float lat(obs) ; float depth(obs) ;
  float speed(obs) ; speed:_FillValue = 9999.f ;
  :featureType = "trajectory" ;
data:
  n = 2, 3 ; a = 1, 2, 3, 4, 5 ; lat = 0, 1, 2, 3, 4 ; depth = 0, 1, 2, 3, 4 ;
  speed = 1, 9999, 3, 4, 5 ;
}
CDL
  ncgen -k nc3 -o "$tmp/lagranto.nc" "$tmp/lagranto.cdl" && seed netcdf "$tmp/lagranto.nc" lagranto.nc
  ncgen -k nc4 -o "$tmp/cf.nc" "$tmp/cf.cdl" && seed netcdf "$tmp/cf.nc" cf.nc
  ncgen -k nc3 -o "$tmp/ragged.nc" "$tmp/ragged.cdl" && seed netcdf "$tmp/ragged.nc" ragged.nc
else
  echo "make_corpus: ncgen (netcdf-bin) not found; NetCDF seeds not written" >&2
fi

# Pipelines, transfer functions, keyframes.
root="$here/../.."
for f in "$root"/pipelines/*.json; do seed pipeline_json "$f" "$(basename "$f")"; done
for f in "$root"/pipelines/*.yaml; do seed pipeline_yaml "$f" "$(basename "$f")"; done
cat >"$tmp/tf.json" <<'JSON'
{"name": "two", "range": [0, 1], "colours": [[0, 0.2, 0.3, 0.9], [1, 0.9, 0.1, 0.1]], "opacities": [[0, 0.1], [0.5, 0.8], [1, 1]]}
JSON
seed transfer_function "$tmp/tf.json" tf.json
cat >"$tmp/keys.json" <<'JSON'
{"keyframes": [{"eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 40}, {"eye": [5, 0, 0], "target": [0, 0.5, 0], "up": [0, 1, 0], "fov": 30}]}
JSON
seed keyframes "$tmp/keys.json" keys.json
du -sh "$out"
