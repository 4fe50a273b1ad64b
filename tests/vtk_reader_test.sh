#!/usr/bin/env bash
# VTK's own readers (Debian's python3-vtk9) see linebake's attribute as the active scalars of the
# .vtp (vtkXMLPolyDataReader) and the .vtk (vtkPolyDataReader, binary and ASCII): ParaView
# colour-maps by the active scalars, so without them a file opens in a plain colour (issue 23).
# The expected names and counts come from `linebake info --json` of the source, not from the
# writers. Usage: vtk_reader_test.sh LINEBAKE. scripts/setup installs python3-vtk9.
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
    print(f"{name}: active scalars {point_name!r} ({info['points']} points), "
          f"{line_name!r} ({info['lines']} lines)")
EOF
echo "vtk_reader_test: passed"
