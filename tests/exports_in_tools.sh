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

# Far-off lines (lines/origin.hpp): UTM-like coordinates whose centimetres float32 cannot hold at
# 5.4e6, baked at `--origin auto`. VTK's readers (python3-vtk9) see the .vtp's and .vtk's float64
# world points equal to the CSV's numbers; pyopenvdb's transform and the glTF's node translation
# put the voxels and the tubes back at the world coordinates.
$python - <<'EOF'
with open("utm.csv", "w") as f:
    f.write("line_id,x,y,z,speed\n")
    for l in range(4):
        for i in range(40):
            f.write(f"{l},{500000.25 + 2.0 * i + 0.01 * l},{5400000.07 + 1.5 * l + 0.03 * i},{120.5 + 0.1 * i},{i}\n")
EOF
check "bake --origin auto" "$bin" bake utm.csv --origin auto --assets tubes,voxels -o utm.lbc.h5
check "export of lines with an origin" "$bin" export utm.lbc.h5 -o utm.glb -o utm.vdb
check "convert --origin auto to vtp" "$bin" convert utm.csv --origin auto -o utm.vtp
check "convert --origin auto to vtk" "$bin" convert utm.csv --origin auto -o utm.vtk
origin=$("$bin" info utm.lbc.h5 --json | $python -c 'import json,sys; print(json.load(sys.stdin)["metadata"]["origin"])')
check "the tools place far-off lines at their world coordinates" $python - "$origin" <<'EOF'
import json, struct, sys
import numpy as np
import pyopenvdb as vdb
import vtk

origin = np.array([float(v) for v in sys.argv[1].split()])
world = np.loadtxt("utm.csv", delimiter=",", skiprows=1)[:, 1:4]
# The first point (as float32 reads it), rounded half away from 0: auto's origin.
first = world[0].astype(np.float32).astype(np.float64)
assert np.array_equal(origin, np.sign(first) * np.floor(np.abs(first) + 0.5)), (origin, first)
lo, hi = world.min(axis=0), world.max(axis=0)
for name, reader in (("utm.vtp", vtk.vtkXMLPolyDataReader()), ("utm.vtk", vtk.vtkPolyDataReader())):
    reader.SetFileName(name)
    reader.Update()
    points = reader.GetOutput().GetPoints()
    assert points.GetDataType() == vtk.VTK_DOUBLE, (name, points.GetDataType())
    got = np.array([points.GetPoint(i) for i in range(points.GetNumberOfPoints())])
    # float32 relative to the origin, added back in float64: the CSV's numbers to half a float32
    # step at the largest distance from the origin (4e-6 here; read as float32 world coordinates
    # they would be up to 0.25 off).
    step = float(np.spacing(np.float32(np.abs(world - origin).max())))
    assert np.abs(got - world).max() <= step / 2 * (1 + 1e-9), (name, np.abs(got - world).max(), step)
    assert np.abs(world.astype(np.float32) - world).max() > 0.01

data = open("utm.glb", "rb").read()
json_len, = struct.unpack_from("<I", data, 12)
doc = json.loads(data[20:20 + json_len])
for node in doc["nodes"]:
    assert node["translation"] == [origin[0], origin[2], -origin[1]], node  # glTF +y is data +z
prims = doc["meshes"][0]["primitives"]
glo = np.min([doc["accessors"][p["attributes"]["POSITION"]]["min"] for p in prims], axis=0)
ghi = np.max([doc["accessors"][p["attributes"]["POSITION"]]["max"] for p in prims], axis=0)
t = np.array(doc["nodes"][0]["translation"])
tube_lo = np.array([glo[0] + t[0], -(ghi[2] + t[2]), glo[1] + t[1]])
tube_hi = np.array([ghi[0] + t[0], -(glo[2] + t[2]), ghi[1] + t[1]])
radius = doc["meshes"][0]["extras"]["linebake_tube_radius"]
assert np.all(np.abs(tube_lo - lo) <= radius + 1e-3) and np.all(np.abs(tube_hi - hi) <= radius + 1e-3), (tube_lo, lo, tube_hi, hi)

density = vdb.read("utm.vdb", "density")
ijk_lo, ijk_hi = density.evalActiveVoxelBoundingBox()
h = density.transform.voxelSize()[0]
vlo = np.array(density.transform.indexToWorld(ijk_lo)) - h / 2
vhi = np.array(density.transform.indexToWorld(ijk_hi)) + h / 2
assert np.all(np.abs(vlo - lo) <= h + 1e-3) and np.all(np.abs(vhi - hi) <= h + 1e-3), (vlo, lo, vhi, hi, h)
print("world", lo, hi, "VDB", vlo, vhi, "glTF", tube_lo, tube_hi)
EOF
# A bake at another origin reads the lines again; baking a cache in place cannot move them.
check "a bake at another origin rebuilds the lines" bash -c '"$0" bake utm.csv --origin 500000,5400000,0 --assets tubes,voxels -o utm.lbc.h5 && "$0" info utm.lbc.h5 | grep -qx "origin      500000 5400000 0"' "$bin"
check "--origin on a cache baked in place is refused" exit_code 1 "$bin" bake utm.lbc.h5 --origin 1,2,3 --assets embree
check "--origin that is not three numbers is refused" exit_code 1 "$bin" convert utm.csv --origin 1,2 -o x.vtp

echo "exports_in_tools: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
