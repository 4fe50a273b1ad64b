#!/usr/bin/env bash
# VTK's own readers (Debian's python3-vtk9) see linebake's attribute as the active scalars of the
# .vtp (vtkXMLPolyDataReader) and the .vtk (vtkPolyDataReader, binary and ASCII): ParaView
# colour-maps by the active scalars, so without them a file opens in a plain colour (issue 23).
# The expected names and counts come from `linebake info --json` of the source, not from the
# writers. And the other way: files VTK's vtkPolyDataWriter writes (METADATA blocks,
# COLOR_SCALARS, both encodings) and a .vtp of surfaces only, read (or refused) by linebake,
# against the values written. Usage: vtk_reader_test.sh LINEBAKE. scripts/setup installs python3-vtk9.
set -euo pipefail
bin=${1:?usage: vtk_reader_test.sh LINEBAKE}
python=/usr/bin/python3
if ! "$python" -c 'import vtk' 2> /dev/null; then
  echo "vtk_reader_test: $python cannot import vtk (scripts/setup installs python3-vtk9)"
  exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Two vertex attributes and one line attribute: the first of each must be the active one.
"$bin" synth aneurysm --scale 0.002 -o "$tmp/lines.h5" 2> /dev/null
"$bin" convert "$tmp/lines.h5" -o "$tmp/source.h5" --derive arc_length,line_length 2> /dev/null
"$bin" info "$tmp/source.h5" --json > "$tmp/info.json"
"$bin" convert "$tmp/source.h5" -o "$tmp/lines.vtp" 2> /dev/null
"$bin" convert "$tmp/source.h5" -o "$tmp/lines.vtk" 2> /dev/null
"$bin" convert "$tmp/source.h5" -o "$tmp/lines_ascii.vtk" --ascii 2> /dev/null
"$python" - "$tmp" << 'EOF'
import json, sys
import vtk

tmp = sys.argv[1]
info = json.load(open(f"{tmp}/info.json"))
point_name, line_name = info["attributes"][0]["name"], info["line_attributes"][0]["name"]
assert len(info["attributes"]) >= 2, "the test needs two vertex attributes"


def check(data, where, name, count, label):
    scalars = data.GetScalars()
    assert scalars is not None, f"{label}: no active {where} scalars"
    assert scalars.GetName() == name, f"{label}: active {where} scalars {scalars.GetName()!r}, not {name!r}"
    assert scalars.GetNumberOfTuples() == count, (
        f"{label}: {scalars.GetNumberOfTuples()} {where} tuples, expected {count}")
    assert scalars.GetNumberOfComponents() == 1, f"{label}: {where} scalars not one component"


readers = [("lines.vtp", vtk.vtkXMLPolyDataReader), ("lines.vtk", vtk.vtkPolyDataReader),
           ("lines_ascii.vtk", vtk.vtkPolyDataReader)]
for name, reader_type in readers:
    reader = reader_type()
    reader.SetFileName(f"{tmp}/{name}")
    reader.Update()
    poly = reader.GetOutput()
    assert poly.GetNumberOfPoints() == info["points"], (name, poly.GetNumberOfPoints())
    assert poly.GetNumberOfLines() == info["lines"], (name, poly.GetNumberOfLines())
    check(poly.GetPointData(), "point", point_name, info["points"], name)
    check(poly.GetCellData(), "cell", line_name, info["lines"], name)
    # Every attribute, with the readers' defaults (a legacy file of SCALARS sections only had
    # shown the first alone: VTK reads one SCALARS unless told ReadAllScalarsOn).
    for data, attributes in ((poly.GetPointData(), info["attributes"]),
                             (poly.GetCellData(), info["line_attributes"])):
        seen = {data.GetArrayName(i) for i in range(data.GetNumberOfArrays())}
        assert {a["name"] for a in attributes} <= seen, (name, seen, attributes)
    print(f"{name}: active scalars {point_name!r} ({info['points']} points), "
          f"{line_name!r} ({info['lines']} lines)")
EOF
# The other way: files VTK's own vtkPolyDataWriter writes, read by linebake. Arrays whose range
# was asked for (ParaView always asks) get a METADATA block after them, inside FIELD data too,
# as do named components (velocity_vx, not velocity_x), and unsigned char scalars are
# COLOR_SCALARS (floats 0..1 in ASCII, bytes in binary). The same data as a .vtp names its
# components too. The expected values are the ones written here.
"$python" - "$tmp" << 'EOF'
import sys
import vtk

tmp = sys.argv[1]
points = vtk.vtkPoints()
for i in range(7):
    points.InsertNextPoint(i, i * i, -i)
cells = vtk.vtkCellArray()
for first, count in ((0, 4), (4, 3)):
    cells.InsertNextCell(count)
    for i in range(first, first + count):
        cells.InsertCellPoint(i)
poly = vtk.vtkPolyData()
poly.SetPoints(points)
poly.SetLines(cells)


def add(data, array, name, values):
    array.SetName(name)
    for v in values:
        array.InsertNextValue(v)
    data.AddArray(array)
    array.GetRange(-1)  # what makes the writer add METADATA


add(poly.GetPointData(), vtk.vtkFloatArray(), "temp", [1, 2, 3, 4, 5, 6, 7])
add(poly.GetPointData(), vtk.vtkDoubleArray(), "speed", [10, 20, 30, 40, 50, 60, 70.5])
colour = vtk.vtkUnsignedCharArray()
colour.SetName("colour")
colour.SetNumberOfComponents(3)
for i in range(7):
    colour.InsertNextTuple3(255, 51 * (i % 6), 0)
poly.GetPointData().SetScalars(colour)
velocity = vtk.vtkFloatArray()
velocity.SetName("velocity")
velocity.SetNumberOfComponents(3)
for c, name in enumerate(("vx", "vy", "vz")):
    velocity.SetComponentName(c, name)
for i in range(7):
    velocity.InsertNextTuple3(i, 2 * i, -i)
poly.GetPointData().AddArray(velocity)
add(poly.GetCellData(), vtk.vtkDoubleArray(), "length", [3.5, 2.25])
add(poly.GetCellData(), vtk.vtkIntArray(), "id", [7, 9])
for binary in (False, True):
    writer = vtk.vtkPolyDataWriter()
    writer.SetFileName(f"{tmp}/from_vtk_{int(binary)}.vtk")
    writer.SetInputData(poly)
    if binary:
        writer.SetFileTypeToBinary()
    writer.Write()
writer = vtk.vtkXMLPolyDataWriter()
writer.SetFileName(f"{tmp}/from_vtk_2.vtp")
writer.SetInputData(poly)
writer.Write()
EOF
for binary in 0 1 2; do
  file=$tmp/from_vtk_$binary.vtk
  [ "$binary" = 2 ] && file=$tmp/from_vtk_2.vtp
  "$bin" info "$file" --json > "$tmp/from_vtk.json"
  "$python" - "$tmp/from_vtk.json" "$binary" << 'EOF'
import json, sys

info = json.load(open(sys.argv[1]))
label = ("vtkPolyDataWriter ASCII", "vtkPolyDataWriter binary", "vtkXMLPolyDataWriter")[int(sys.argv[2])]
assert (info["lines"], info["points"]) == (2, 7), (label, info["lines"], info["points"])
ranges = {a["name"]: (a["min"], a["max"]) for a in info["attributes"]}
expected = {"temp": (1, 7), "speed": (10, 70.5), "velocity_vx": (0, 6), "velocity_vy": (0, 12),
            "velocity_vz": (-6, 0)}
if "XML" not in label:  # COLOR_SCALARS, 0..1 (the .vtp holds the bytes as they are)
    expected.update({"colour_x": (1, 1), "colour_y": (0, 1), "colour_z": (0, 0)})
else:
    expected.update({"colour_x": (255, 255), "colour_y": (0, 255), "colour_z": (0, 0)})
for name, (low, high) in expected.items():
    assert name in ranges, (label, name, sorted(ranges))
    assert abs(ranges[name][0] - low) < 1e-6 and abs(ranges[name][1] - high) < 1e-6, (
        label, name, ranges[name])
lines = {a["name"]: (a["min"], a["max"]) for a in info["line_attributes"]}
assert lines == {"length": (2.25, 3.5), "id": (7, 9)}, (label, lines)
print(f"{label}: 2 lines, 7 points, {len(ranges)} vertex and {len(lines)} line attributes")
EOF
done
# A surface in a .vtp (vtkXMLPolyDataWriter, Polys only) is no line set: refused, not read as an
# empty one. A vtkStringArray in a .vtp's FieldData, in each of the writer's modes (appended, its
# default, had been skipped), is the line set's metadata.
"$python" - "$tmp" << 'EOF'
import sys
import vtk

tmp = sys.argv[1]


def one_cell(points, surface):
    coordinates = vtk.vtkPoints()
    for i in range(points):
        coordinates.InsertNextPoint(i, i * i, 0)
    cells = vtk.vtkCellArray()
    cells.InsertNextCell(points)
    for i in range(points):
        cells.InsertCellPoint(i)
    poly = vtk.vtkPolyData()
    poly.SetPoints(coordinates)
    poly.SetPolys(cells) if surface else poly.SetLines(cells)
    return poly


def write(poly, path, mode="Appended"):
    writer = vtk.vtkXMLPolyDataWriter()
    writer.SetFileName(path)
    writer.SetInputData(poly)
    getattr(writer, "SetDataModeTo" + mode)()
    writer.Write()


write(one_cell(4, True), f"{tmp}/surface.vtp")
for mode in ("Appended", "Binary", "Ascii"):
    poly = one_cell(3, False)
    author = vtk.vtkStringArray()
    author.SetName("author")
    author.InsertNextValue("Ada Lovelace")
    poly.GetFieldData().AddArray(author)
    write(poly, f"{tmp}/strings_{mode}.vtp", mode)
EOF
status=0
"$bin" info "$tmp/surface.vtp" > /dev/null 2> "$tmp/surface.err" || status=$?
[ "$status" -eq 2 ] && grep -q 'surface.vtp: Piece: no Lines cells, only surfaces (1 Polys, 0 Strips)' "$tmp/surface.err" || {
  echo "vtk_reader_test: a .vtp of Polys only: exit $status, $(cat "$tmp/surface.err")"
  exit 1
}
echo "vtkXMLPolyDataWriter Polys only: refused (exit 2)"
for mode in Appended Binary Ascii; do
  "$bin" info "$tmp/strings_$mode.vtp" --json | "$python" -c "import json, sys; m = json.load(sys.stdin)['metadata']; assert m.get('author') == 'Ada Lovelace', ('$mode', m)"
done
echo "vtkXMLPolyDataWriter FieldData strings (appended, binary, ascii): the metadata"
echo "vtk_reader_test: passed"
