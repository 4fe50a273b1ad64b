#!/usr/bin/env bash
# The exports read by the tools users open them with, from Debian's packages (issue 23):
# pyopenvdb reads every grid of the VDB (readAll), the VDB and the glTF of the same data line up
# once the glTF's +y-up convention is undone (the conversion is done here, not by linebake), the
# glTF's COLOR_0, TEXCOORD_0 and lines primitives are what docs/cli.md says, parsed from the GLB
# bytes with nothing of linebake's. scripts/setup installs python3-openvdb.
set -u
bin="$(readlink -f "$1")"
# shellcheck source=tests/check.sh
source "$(dirname "$0")/check.sh"
cd "$tmp" || exit 1
python=/usr/bin/python3
$python -c 'import pyopenvdb, numpy' || { echo "python3-openvdb is missing (scripts/setup)"; exit 1; }

"$bin" bake "synth:convection?scale=0.003" -o a.lbc.h5 --assets tubes,voxels >/dev/null 2>&1
check "export writes the glTF and the VDB" "$bin" export a.lbc.h5 -o a.glb -o a.vdb --lines
check "export writes .gltf and .bin" "$bin" export a.lbc.h5 -o b.gltf --line-strips --lines
check "export --axes raw" "$bin" export a.lbc.h5 -o raw.glb --axes raw --colors none
lines=$("$bin" info a.lbc.h5 --json | $python -c 'import json,sys; print(json.load(sys.stdin)["lines"])')

check "pyopenvdb, the glTF and the VDB agree" $python - "$lines" <<'EOF'
import json, struct, sys
import numpy as np
import pyopenvdb as vdb

lines = int(sys.argv[1])

def gltf(path, bin_path=None):
    data = open(path, "rb").read()
    if bin_path is None:
        magic, version, length = struct.unpack_from("<4sII", data)
        assert magic == b"glTF" and version == 2 and length == len(data)
        json_len, = struct.unpack_from("<I", data, 12)
        doc = json.loads(data[20:20 + json_len])
        bin_len, = struct.unpack_from("<I", data, 20 + json_len)
        blob = data[28 + json_len:28 + json_len + bin_len]
    else:
        doc, blob = json.loads(data), open(bin_path, "rb").read()
    return doc, blob

def values(doc, blob, index):
    a = doc["accessors"][index]
    view = doc["bufferViews"][a["bufferView"]]
    dtype = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}[a["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    size = np.dtype(dtype).itemsize * width
    stride = view.get("byteStride", size)
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    rows = [np.frombuffer(blob, dtype, width, start + i * stride) for i in range(a["count"])]
    return np.array(rows)

doc, blob = gltf("a.glb")
tubes, line_mesh = doc["meshes"]
# COLOR_0 and TEXCOORD_0 on every tube primitive, normalised unsigned integers, one per vertex.
lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
for p in tubes["primitives"]:
    at = p["attributes"]
    n = doc["accessors"][at["POSITION"]]["count"]
    colour, uv = doc["accessors"][at["COLOR_0"]], doc["accessors"][at["TEXCOORD_0"]]
    assert (colour["type"], colour["componentType"], colour["normalized"], colour["count"]) == ("VEC4", 5121, True, n), colour
    assert (uv["type"], uv["componentType"], uv["normalized"], uv["count"]) == ("VEC2", 5123, True, n), uv
    t = values(doc, blob, at["TEXCOORD_0"])
    assert (t[:, 1] == 32768).all()
    c = values(doc, blob, at["COLOR_0"])
    assert (c[:, 3] == 255).all() and c[:, :3].std() > 0, "COLOR_0 is not colour mapped"
    # The colour follows the attribute: the same u, the same colour.
    assert all(len({tuple(x) for x in c[t[:, 0] == u]}) == 1 for u in np.unique(t[:, 0])[:50])
    a = doc["accessors"][at["POSITION"]]
    lo, hi = np.minimum(lo, a["min"]), np.maximum(hi, a["max"])
# The lines: one indexed LINES primitive, a segment per pair of consecutive points.
assert len(line_mesh["primitives"]) == 1 and line_mesh["primitives"][0]["mode"] == 1
points = doc["accessors"][line_mesh["primitives"][0]["attributes"]["POSITION"]]["count"]
segments = doc["accessors"][line_mesh["primitives"][0]["indices"]]["count"] // 2
assert segments == points - lines, (segments, points, lines)
# --line-strips in a .gltf with its .bin: one LINE_STRIP per polyline.
doc_b, blob_b = gltf("b.gltf", "b.bin")
assert doc_b["buffers"][0]["uri"] == "b.bin" and doc_b["buffers"][0]["byteLength"] == len(blob_b)
strips = doc_b["meshes"][1]["primitives"]
assert len(strips) == lines and all(p["mode"] == 3 for p in strips), len(strips)

# glTF's +y is up; undo it the way importers do (Blender: x, -z, y) to get the data's axes.
data_lo = np.array([lo[0], -hi[2], lo[1]])
data_hi = np.array([hi[0], -lo[2], hi[1]])
raw, raw_blob = gltf("raw.glb")
rlo = np.min([raw["accessors"][p["attributes"]["POSITION"]]["min"] for p in raw["meshes"][0]["primitives"]], axis=0)
rhi = np.max([raw["accessors"][p["attributes"]["POSITION"]]["max"] for p in raw["meshes"][0]["primitives"]], axis=0)
assert np.allclose(rlo, data_lo, atol=1e-5) and np.allclose(rhi, data_hi, atol=1e-5), (rlo, data_lo)
assert "COLOR_0" not in raw["meshes"][0]["primitives"][0]["attributes"]

grids, meta = vdb.readAll("a.vdb")
names = sorted(g.name for g in grids)
assert names == ["attribute_chord_max", "attribute_density", "density", "line_count"], names
assert all(type(g).__name__ == "FloatGrid" for g in grids)
density = next(g for g in grids if g.name == "density")
assert density.gridClass == "fog volume"
dmin, dmax = density.evalMinMax()
assert 0 < dmin and dmax == 1.0, (dmin, dmax)
ijk_lo, ijk_hi = density.evalActiveVoxelBoundingBox()
h = density.transform.voxelSize()[0]
vlo = np.array(density.transform.indexToWorld(ijk_lo)) - h / 2
vhi = np.array(density.transform.indexToWorld(ijk_hi)) + h / 2
# The voxels hold the lines, the tubes reach a radius further: they agree to a voxel and a radius.
radius = tubes["extras"]["linebake_tube_radius"]
tolerance = h + radius + 1e-4
assert np.all(np.abs(vlo - data_lo) <= tolerance) and np.all(np.abs(vhi - data_hi) <= tolerance), (vlo, data_lo, vhi, data_hi, tolerance)
# Without the conversion they would not: convection is 16 high and 1 deep.
print("VDB", vlo, vhi, "glTF in data axes", data_lo, data_hi, "voxel", h, "radius", radius)
EOF

echo "exports_in_tools: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
