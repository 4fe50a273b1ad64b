"""LineSet from NumPy and back: every writable format, zero-copy views, info() against the CLI,
errors naming the file, CF trajectories written by xarray and netCDF4."""

import os
import subprocess
import sys
import types
import warnings

import numpy as np
import pytest

import linebake
from conftest import SYNTH, cli_error, cli_json, resident_bytes


def sample_arrays():
    """Three lines of 4, 7 and 2 points with random float32 values (fixed seed)."""
    rng = np.random.default_rng(24)
    offsets = np.array([0, 4, 11, 13], dtype=np.uint64)
    points = rng.uniform(-50, 50, size=(13, 3)).astype(np.float32)
    attributes = {
        "speed": rng.uniform(0, 3, 13).astype(np.float32),
        "temperature": rng.normal(280, 10, 13).astype(np.float32),
    }
    line_attributes = {"seed_id": np.array([7, 8, 9], dtype=np.float32)}
    return points, offsets, attributes, line_attributes


def writable_formats():
    return [f for f in linebake.formats() if f["write"]]


def test_arrays_in_and_out():
    points, offsets, attributes, line_attributes = sample_arrays()
    lines = linebake.LineSet(points, offsets, attributes, line_attributes, {"units": "km"})
    assert (lines.line_count, lines.point_count) == (3, 13)
    assert lines.segment_count == 3 + 6 + 1  # points - 1 per line
    assert lines.points.dtype == np.float32 and lines.points.shape == (13, 3)
    assert lines.offsets.dtype == np.uint64
    np.testing.assert_array_equal(lines.points, points)
    np.testing.assert_array_equal(lines.offsets, offsets)
    assert list(lines.attributes) == ["speed", "temperature"]
    for name, values in attributes.items():
        np.testing.assert_array_equal(lines.attributes[name], values)
    np.testing.assert_array_equal(lines.line_attributes["seed_id"], [7, 8, 9])
    np.testing.assert_array_equal(lines.line(1), points[4:11])
    # Negative indices count from the end, as for Python's sequences.
    np.testing.assert_array_equal(lines.line(-1), points[11:13])
    np.testing.assert_array_equal(lines.line(-3), points[0:4])
    for out_of_range in (3, -4):
        with pytest.raises(IndexError):
            lines.line(out_of_range)
    assert lines.metadata == {"units": "km"}


def test_arrays_may_be_lists():
    # The stub's ArrayLike: nested lists as np.asarray takes them, the same line set.
    points, offsets, _, _ = sample_arrays()
    from_lists = linebake.LineSet(points.tolist(), [int(o) for o in offsets])
    assert from_lists.same_data(linebake.LineSet(points, offsets))


def test_mappings_may_be_any_mapping():
    # The stub's Mapping: a read-only mapping or pairs work as a dict does; a non-str metadata
    # value is a TypeError naming it (it was "Unable to cast").
    points, offsets, attributes, line_attributes = sample_arrays()
    proxy = linebake.LineSet(points, offsets, types.MappingProxyType(attributes),
                             list(line_attributes.items()), types.MappingProxyType({"u": "km"}))
    assert proxy.same_data(linebake.LineSet(points, offsets, attributes, line_attributes))
    assert proxy.metadata == {"u": "km"}
    with pytest.raises(TypeError, match="metadata: keys and values are str, got 'u': 1"):
        linebake.LineSet(points, offsets, metadata={"u": 1})
    with pytest.raises(TypeError, match="attribute: expected a mapping, got 5"):
        linebake.LineSet(points, offsets, attributes=5)


def test_paths_may_be_pathlib_paths(tmp_path):
    # The stub's StrPath: a pathlib.Path works wherever a str does; anything else is a TypeError
    # naming the call.
    points, offsets, attributes, line_attributes = sample_arrays()
    lines = linebake.LineSet(points, offsets, attributes, line_attributes)
    path = tmp_path / "lines.h5"
    linebake.write(lines, path)
    back = linebake.read(path)
    assert back.same_data(lines) and back.source == str(path)
    cache = tmp_path / "lines.lbc.h5"
    linebake.bake(path, cache, tube_sides=4)
    assert linebake.open_cache(cache).lines().same_data(lines)
    with pytest.raises(TypeError, match="read: expected a str, bytes or os.PathLike, got 42"):
        linebake.read(42)
    with pytest.raises(TypeError, match="bake: expected a str, bytes or os.PathLike, got None"):
        linebake.bake(None, str(cache))


def test_threads_making_the_first_arrays_do_not_deadlock():
    # In a fresh interpreter, eight threads make the module's first NumPy arrays at once (a line
    # set's views): pybind11's first lookup of NumPy's API, under a guard that waits holding the
    # GIL, hung them until the module looked it up at import.
    script = (
        "import threading, numpy as np, linebake\n"
        "points = np.zeros((4, 3), np.float32); offsets = np.array([0, 4], np.uint64)\n"
        "def make(): linebake.LineSet(points, offsets).points.sum()\n"
        "threads = [threading.Thread(target=make) for _ in range(8)]\n"
        "[t.start() for t in threads]; [t.join() for t in threads]\n"
        "print('done')\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, env=os.environ)
    assert done.returncode == 0 and done.stdout.strip() == "done", done.stderr


def test_threads_reading_hdf5_files_at_once(tmp_path):
    # Eight threads read HDF5 files at once, each a fresh copy (every read walks its metadata in
    # an isolated process first). A child forked while another thread was inside HDF5 inherited
    # its global lock and stalled to its limit: 8 of these 48 reads were called malformed. With
    # threads, the walk runs in linebake-probe, a fresh process.
    points = np.arange(300, dtype=np.float32).reshape(100, 3)
    source = tmp_path / "source.h5"
    linebake.write(linebake.LineSet(points, np.array([0, 40, 100], dtype=np.uint64)), source)
    script = (
        "import shutil, sys, threading, linebake\n"
        "source, folder = sys.argv[1], sys.argv[2]\n"
        "errors = []\n"
        "def work(k):\n"
        "    for r in range(6):\n"
        "        copy = f'{folder}/copy_{k}_{r}.h5'\n"
        "        shutil.copy(source, copy)\n"
        "        try:\n"
        "            assert linebake.read(copy).points.shape == (100, 3)\n"
        "        except Exception as e:\n"
        "            errors.append(str(e))\n"
        "threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]\n"
        "[t.start() for t in threads]; [t.join() for t in threads]\n"
        "print(len(errors), errors[:2])\n")
    env = dict(os.environ, LINEBAKE_ISOLATION_SECONDS="5")
    done = subprocess.run([sys.executable, "-c", script, str(source), str(tmp_path)],
                          capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0 and done.stdout.startswith("0 "), done.stdout + done.stderr


def test_a_warning_made_an_error_writes_nothing(tmp_path):
    points, offsets, attributes, line_attributes = sample_arrays()
    lines = linebake.LineSet(points, offsets, attributes, line_attributes)
    path = tmp_path / "lines.obj"  # OBJ cannot hold the line attributes: a warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning, match="cannot hold"):
            linebake.write(lines, str(path))
    assert not path.exists()


def stale_temporary_of(path):
    """A temporary of `path` as a process that is gone left it (atomic_file.cpp's name)."""
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    host = "".join("_" if c in "/.-" else c for c in os.uname().nodename)
    stale = path.parent / f"{path.name}.tmp-{host}-{gone.pid}-0"
    stale.write_bytes(b"x" * 100)
    return stale


def test_library_notes_are_note_warnings(tmp_path):
    # The library's notes had been printed to stderr, which a notebook does not show and no
    # warnings filter sees.
    points, offsets, attributes, _ = sample_arrays()
    attributes["speed"][2] = np.nan
    lines = linebake.LineSet(points, offsets, attributes)
    path = tmp_path / "lines.vtk"
    stale = stale_temporary_of(path)
    with pytest.warns(linebake.Note) as caught:
        linebake.write(lines, path, ascii=True)
    messages = [str(w.message) for w in caught if w.category is linebake.Note]
    assert any("1 NaN or infinite value(s) are written as nan" in m for m in messages), messages
    assert any(f"removed 1 temporary file(s) of {path}" in m for m in messages), messages
    assert issubclass(linebake.Note, UserWarning) and not stale.exists() and path.exists()
    assert all(w.filename == __file__ for w in caught), [w.filename for w in caught]
    # A filter that makes an error of a note stops the call; nothing is written.
    path.unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("error", linebake.Note)
        with pytest.raises(linebake.Note, match="nan or inf"):
            linebake.write(lines, path, ascii=True)
    assert not path.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fmt", writable_formats(), ids=lambda f: f["name"])
def test_round_trip_every_writable_format(tmp_path, fmt):
    points, offsets, attributes, line_attributes = sample_arrays()
    lines = linebake.LineSet(points, offsets, attributes, line_attributes)
    path = str(tmp_path / ("lines" + fmt["extensions"][0]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        linebake.write(lines, path)
    # Formats without line attributes say so: the CLI's "cannot hold" warning.
    lost = [str(w.message) for w in caught]
    assert bool(lost) == (not fmt["line_attributes"]), lost
    back = linebake.read(path)
    np.testing.assert_array_equal(back.points, points)
    np.testing.assert_array_equal(back.offsets, offsets)
    assert list(back.attributes) == list(attributes)
    for name, values in attributes.items():
        np.testing.assert_array_equal(back.attributes[name], values)
    if fmt["line_attributes"]:
        np.testing.assert_array_equal(back.line_attributes["seed_id"], [7, 8, 9])
    # The CLI reads the same file to the same figures.
    assert back.info() == cli_json("info", path)


def test_strict_write_refuses_losing_data(tmp_path):
    points, offsets, attributes, line_attributes = sample_arrays()
    lines = linebake.LineSet(points, offsets, attributes, line_attributes)
    with pytest.raises(linebake.Error, match="cannot hold line attribute seed_id"):
        linebake.write(lines, str(tmp_path / "x.csv"), strict=True)
    assert not os.path.exists(tmp_path / "x.csv")


@pytest.mark.parametrize("fmt", writable_formats(), ids=lambda f: f["name"])
def test_empty_lines_are_kept_or_said_lost(tmp_path, fmt):
    # Three lines, the middle one without points. CSV (a row per point) and OBJ (an `l` needs a
    # vertex) cannot hold it: they say so and write a file that reads back as the other two.
    points = np.arange(15, dtype=np.float32).reshape(5, 3)
    lines = linebake.LineSet(points, np.array([0, 3, 3, 5], dtype=np.uint64))
    path = str(tmp_path / ("empty" + fmt["extensions"][0]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        linebake.write(lines, path)
    lost = [str(w.message) for w in caught if "empty line" in str(w.message)]
    keeps = fmt["name"] not in ("csv", "obj")
    assert lost == ([] if keeps else
                    [f"{path}: {fmt['name']} cannot hold 1 empty line (without points); "
                     "they are not written"])
    back = linebake.read(path)
    np.testing.assert_array_equal(back.points, points)
    np.testing.assert_array_equal(back.offsets, [0, 3, 3, 5] if keeps else [0, 3, 5])


def address(array):
    return array.__array_interface__["data"][0]


def test_views_share_the_line_sets_memory():
    points, offsets, attributes, _ = sample_arrays()
    lines = linebake.LineSet(points, offsets, attributes)
    first, second = lines.points, lines.points
    assert address(first) == address(second)
    assert address(lines.offsets) == address(lines.offsets)
    assert address(lines.attributes["speed"]) == address(lines.attributes["speed"])
    # A line is a slice of the same buffer: 4 points of 12 bytes in.
    assert address(lines.line(1)) == address(first) + 4 * 3 * 4
    # The input arrays were copied in; the views are the line set's own and read-only.
    assert address(first) != address(points)
    assert not first.flags.writeable
    with pytest.raises(ValueError):
        first[0, 0] = 1
    # A view keeps the line set alive.
    del lines
    np.testing.assert_array_equal(second, points)


def test_bad_arrays_are_value_errors():
    points, offsets, _, _ = sample_arrays()
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        linebake.LineSet(points.reshape(-1), offsets)
    with pytest.raises(ValueError, match="point count"):
        linebake.LineSet(points, np.array([0, 4, 12], dtype=np.uint64))
    with pytest.raises(ValueError, match="negative"):
        linebake.LineSet(points, np.array([0, -1, 13]))
    with pytest.raises(ValueError, match="speed"):
        linebake.LineSet(points, offsets, {"speed": np.zeros(5, np.float32)})


def test_info_matches_cli():
    lines = linebake.read(SYNTH)
    assert lines.info() == cli_json("info", SYNTH)
    assert lines.info()["lines"] == lines.line_count


def test_validate_and_derive():
    points, offsets, attributes, _ = sample_arrays()
    points[2] = np.nan  # an invalid point splits line 0 into 2 + 1 points, the 1 is dropped
    lines = linebake.LineSet(points, offsets, attributes)
    repaired, report = lines.validate("repair")
    assert report["invalid_points"] == 1 and report["repaired"]
    assert repaired.point_count == 12 - 1 and repaired.line_count == 3
    with pytest.raises(linebake.Error):
        lines.validate("reject")
    derived = repaired.with_derived(["arc_length", "line_length"])
    # Hand-computed: arc length of the second line's points.
    line = derived.line(1).astype(np.float64)
    steps = np.linalg.norm(np.diff(line, axis=0), axis=1)
    start = int(derived.offsets[1])
    arc = derived.attributes["arc_length"][start:start + len(line)]
    np.testing.assert_allclose(arc, np.concatenate([[0], np.cumsum(steps)]), rtol=1e-6)
    np.testing.assert_allclose(derived.line_attributes["line_length"][1], steps.sum(), rtol=1e-6)


def test_bad_input_names_the_file(tmp_path):
    bad = tmp_path / "broken.vtp"
    bad.write_text("<VTKFile type='PolyData'><PolyData><Piece NumberOfPoints='x'>")
    with pytest.raises(linebake.InputError) as caught:
        linebake.read(str(bad))
    assert str(bad) in str(caught.value)
    assert caught.value.file == str(bad)
    assert str(caught.value) == cli_error("info", bad)
    assert isinstance(caught.value, linebake.Error) and isinstance(caught.value, RuntimeError)

    missing = str(tmp_path / "missing.binlines")
    with pytest.raises(linebake.Error) as caught:
        linebake.read(missing)
    assert str(caught.value) == cli_error("info", missing)

    truncated = tmp_path / "short.binlines"
    linebake.write(linebake.LineSet(*sample_arrays()[:3]), str(truncated))
    truncated.write_bytes(truncated.read_bytes()[:40])
    with pytest.raises(linebake.InputError) as caught:
        linebake.read(str(truncated))
    assert str(caught.value) == cli_error("info", truncated)


def trajectories():
    """Three trajectories of up to 5 observations; the last is 3 long (NaN-filled after)."""
    rng = np.random.default_rng(7)
    lon = rng.uniform(-20, 20, (3, 5))
    lat = rng.uniform(30, 60, (3, 5))
    alt = rng.uniform(0, 9000, (3, 5))
    temperature = rng.uniform(220, 300, (3, 5))
    for array in (lon, lat, alt, temperature):
        array[2, 3:] = np.nan
    return lon, lat, alt, temperature


def test_cf_trajectory_written_by_xarray(tmp_path):
    xr = pytest.importorskip("xarray")
    lon, lat, alt, temperature = trajectories()
    dims = ("trajectory", "obs")
    ds = xr.Dataset(
        {
            "lon": (dims, lon, {"standard_name": "longitude", "units": "degrees_east"}),
            "lat": (dims, lat, {"standard_name": "latitude", "units": "degrees_north"}),
            "alt": (dims, alt, {"standard_name": "altitude", "units": "m"}),
            "temperature": (dims, temperature, {"units": "K"}),
            "trajectory_id": ("trajectory", np.arange(3), {"cf_role": "trajectory_id"}),
        },
        attrs={"featureType": "trajectory", "Conventions": "CF-1.8"},
    )
    path = str(tmp_path / "traj.nc")
    ds.to_netcdf(path, engine="netcdf4")
    lines = linebake.read(path)
    assert lines.info()["format"] == "netcdf"
    lengths = [5, 5, 3]
    np.testing.assert_array_equal(lines.offsets, np.cumsum([0] + lengths))
    valid = ~np.isnan(lon)
    expected = np.stack([lon[valid], lat[valid], alt[valid]], axis=1).astype(np.float32)
    np.testing.assert_array_equal(lines.points, expected)
    np.testing.assert_array_equal(lines.attributes["temperature"],
                                  temperature[valid].astype(np.float32))


def test_cf_contiguous_ragged_written_by_netcdf4(tmp_path):
    netCDF4 = pytest.importorskip("netCDF4")
    lon, lat, alt, _ = trajectories()
    valid = ~np.isnan(lon)
    path = str(tmp_path / "ragged.nc")
    with netCDF4.Dataset(path, "w") as nc:
        nc.featureType = "trajectory"
        nc.createDimension("trajectory", 3)
        nc.createDimension("obs", int(valid.sum()))
        row_size = nc.createVariable("row_size", "i4", ("trajectory",))
        row_size.sample_dimension = "obs"
        row_size[:] = valid.sum(axis=1)
        for name, values, standard in (("lon", lon, "longitude"), ("lat", lat, "latitude"),
                                       ("z", alt, "altitude")):
            variable = nc.createVariable(name, "f8", ("obs",))
            variable.standard_name = standard
            variable[:] = values[valid]
    lines = linebake.read(path)
    np.testing.assert_array_equal(lines.offsets, [0, 5, 10, 13])
    expected = np.stack([lon[valid], lat[valid], alt[valid]], axis=1).astype(np.float32)
    np.testing.assert_array_equal(lines.points, expected)


def test_read_holds_a_whole_format_within_memory_budget(tmp_path):
    # A VTK is read whole: past memory_budget, BudgetExceeded names the file and where it was
    # refused, before the points are allocated; unlimited reads it.
    points = np.arange(3 * 200000, dtype=np.float32).reshape(-1, 3)
    path = tmp_path / "big.vtk"
    linebake.write(linebake.LineSet(points, np.array([0, 200000], dtype=np.uint64)), path)
    with pytest.raises(linebake.BudgetExceeded, match=r"big.vtk: vtk is read whole: at POINTS"):
        linebake.read(path, memory_budget="1M")
    assert linebake.read(path, memory_budget="unlimited").points.shape == (200000, 3)
    with pytest.raises(linebake.Error):
        linebake.read(path, memory_budget="lots")


def test_read_gathers_a_streamed_format_within_memory_budget(tmp_path):
    # A .binlines streams: read gathers it in batches within memory_budget (12 MiB past what
    # the process holds once the data is written), refused where 3,000,000 points (36 MB, and
    # their arrays' growth) would pass it, or at a line that alone would.
    points = np.arange(3 * 3000000, dtype=np.float32).reshape(-1, 3)
    one_line = tmp_path / "one.binlines"
    linebake.write(linebake.LineSet(points, np.array([0, 3000000], dtype=np.uint64)), one_line)
    many = tmp_path / "many.binlines"
    offsets = np.arange(0, 3000001, 100, dtype=np.uint64)
    linebake.write(linebake.LineSet(points, offsets), many)
    rss = int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    budget = str(rss + (12 << 20))
    with pytest.raises(
        linebake.BudgetExceeded,
        match=r"one.binlines: line 0 \(byte offset 12\) has 3000000 points, read whole",
    ):
        linebake.read(one_line, memory_budget=budget)
    with pytest.raises(linebake.BudgetExceeded, match=r"many.binlines: read whole, its first"):
        linebake.read(many, memory_budget=budget)
    whole = linebake.read(many, memory_budget="unlimited")
    np.testing.assert_array_equal(whole.points, points)
    np.testing.assert_array_equal(whole.offsets, offsets)


@pytest.mark.parametrize("budget", ["0", "0K", 0])
def test_a_memory_budget_of_zero_is_a_usage_error(tmp_path, budget):
    # 0 bytes leaves no room for any work ("unlimited" is the word for no budget), as on the
    # command line: read, bake and render alike.
    points = np.arange(3 * 10, dtype=np.float32).reshape(-1, 3)
    path = tmp_path / "small.binlines"
    linebake.write(linebake.LineSet(points, np.array([0, 10], dtype=np.uint64)), path)
    # Each naming its call's argument (compare's and render's had named --memory-budget).
    zero = "memory_budget: a memory budget of 0 bytes leaves no room for any work"
    with pytest.raises(linebake.UsageError, match="^read: " + zero):
        linebake.read(path, memory_budget=str(budget))
    with pytest.raises(linebake.UsageError, match="^bake: " + zero):
        linebake.bake(path, tmp_path / "small.lbc.h5", memory_budget=budget)
    with pytest.raises(linebake.UsageError, match="^LineSet: " + zero):
        linebake.LineSet(points, np.array([0, 10], dtype=np.uint64), memory_budget=budget)
    image = np.zeros((16, 16, 3), np.float32)
    with pytest.raises(linebake.UsageError, match="^compare: " + zero):
        linebake.compare(image, image, memory_budget=budget)
    assert not (tmp_path / "small.lbc.h5").exists()



def test_read_at_an_origin_keeps_far_off_digits(tmp_path):
    # UTM-like coordinates: float32 steps by 0.5 at 5.4e6, so only relative to an origin do the
    # centimetres survive; LineSet.origin says it and points + origin are the world coordinates.
    csv = tmp_path / "utm.csv"
    world = np.array([[500000.25, 5400000.07, 12.5], [500001.5, 5400000.93, 13.0]])
    csv.write_text("line_id,x,y,z\n" + "".join(f"0,{x!r},{y!r},{z!r}\n" for x, y, z in world))
    plain = linebake.read(csv)
    assert plain.origin is None
    assert np.abs(plain.points.astype(np.float64) - world).max() > 0.05
    for origin in [(500000, 5400000, 0), np.array([500000.0, 5400000.0, 0.0]), "500000,5400000,0"]:
        local = linebake.read(csv, origin=origin)
        assert local.origin == (500000.0, 5400000.0, 0.0)
        assert local.metadata["origin"] == "500000 5400000 0"
        expected = (world - [500000, 5400000, 0]).astype(np.float32)
        assert np.array_equal(local.points, expected)
    auto = linebake.read(csv, origin="auto")
    assert auto.origin == (500000.0, 5400000.0, 13.0)  # the first point, rounded
    # Written where the format holds float64, the world coordinates come back.
    linebake.write(local, tmp_path / "w.vtp")
    assert np.array_equal(linebake.read(tmp_path / "w.vtp", origin=(500000, 5400000, 0)).points,
                          local.points)
    for bad in [(1, 2), ("a", 1, 2), 5, b"1,2,3"]:
        with pytest.raises(TypeError, match="origin"):
            linebake.read(csv, origin=bad)
    with pytest.raises(linebake.UsageError, match="origin"):
        linebake.read(csv, origin="1,2")
    # "" is not None, and a number that is not finite no origin.
    for bad in ["", (float("nan"), 0, 0), [0, float("inf"), 0]]:
        with pytest.raises(linebake.UsageError, match="read: origin"):
            linebake.read(csv, origin=bad)


def test_an_origin_in_metadata_is_checked_and_counts_in_same_data():
    points = np.array([[0, 0, 0], [1, 2, 3]], np.float32)
    with pytest.raises(ValueError, match="origin"):
        linebake.LineSet(points, [0, 2], metadata={"origin": "lower-left"})
    at = linebake.LineSet(points, [0, 2], metadata={"origin": "5e5, 5.4e6, -0"})
    assert at.origin == (500000.0, 5400000.0, 0.0)
    assert at.metadata["origin"] == "500000 5400000 0"  # the one text of those numbers
    # The same local points elsewhere are other world points; no origin is (0, 0, 0).
    assert not at.same_data(linebake.LineSet(points, [0, 2]))
    assert linebake.LineSet(points, [0, 2]).same_data(
        linebake.LineSet(points, [0, 2], metadata={"origin": "0 0 0"}))


def test_values_float32_cannot_hold_are_refused_naming_their_row():
    # A finite float64 past float32's range became an infinity with only NumPy's RuntimeWarning;
    # the file readers refuse it naming the row, and so does LineSet. float32's largest value,
    # and NaN or infinities given as such (data that validation counts), are kept.
    points = np.zeros((4, 3))
    points[2, 1] = 1e39
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no cast ran: NumPy warned of none
        with pytest.raises(ValueError, match=r"^points: row 2: 1e\+39 is outside "
                                             r"float32's range \(magnitude above 3.4028235e38\)"):
            linebake.LineSet(points, [0, 2, 4])
        with pytest.raises(ValueError, match=r"^points: row 2: "):
            linebake.LineSet(points.tolist(), [0, 2, 4])
        edge = np.zeros((2, 3))
        edge[1] = [np.finfo(np.float32).max, -np.inf, np.nan]
        kept = linebake.LineSet(edge, [0, 2])
        assert kept.points[1, 0] == np.finfo(np.float32).max
        assert np.isneginf(kept.points[1, 1]) and np.isnan(kept.points[1, 2])
        with pytest.raises(ValueError, match=r"^attribute 'speed': point 3: -4e\+40 is outside"):
            linebake.LineSet(np.zeros((4, 3)), [0, 2, 4], {"speed": [0.0, 1.0, 2.0, -4e40]})
        with pytest.raises(ValueError, match=r"^line attribute 'id': line 1: 1e\+300 is outside"):
            linebake.LineSet(np.zeros((4, 3)), [0, 2, 4], line_attributes={"id": np.array([1.0, 1e300])})


def test_copies_are_held_within_the_memory_budget():
    # 4 million float64 points: their float32 copy (48 MB) and the conversion before it (48 MB),
    # reserved before either is made; exactly float32 C-order points need the copy alone.
    n = 4_000_000
    wide = np.zeros((n, 3))
    narrow = np.zeros((n, 3), np.float32)
    offsets = np.array([0, n], np.uint64)
    mib = 1 << 20
    with pytest.raises(linebake.BudgetExceeded,
                       match=r"^LineSet: copying 4000000 points, 1 lines and 0 attributes needs "
                             r"about 91.55 MiB"):
        linebake.LineSet(wide, offsets, memory_budget=resident_bytes() + 70 * mib)
    kept = linebake.LineSet(narrow, offsets, memory_budget=resident_bytes() + 70 * mib)
    assert kept.points.shape == (n, 3)
    # A float64 attribute of 4 million values: 16 MB converted and 16 MB copied more.
    with pytest.raises(linebake.BudgetExceeded, match=r"1 attributes needs about 122.07 MiB"):
        linebake.LineSet(wide, offsets, {"t": np.zeros(n)}, memory_budget=resident_bytes() + 70 * mib)
    with pytest.raises(linebake.UsageError, match="LineSet: memory_budget: bad size"):
        linebake.LineSet(narrow, offsets, memory_budget="lots")


def test_attributes_as_an_iterator_of_pairs():
    """zip(names, arrays) had been spent by the budget's look and left no attributes."""
    points, offsets, attributes, line_attributes = sample_arrays()
    lines = linebake.LineSet(points, offsets, zip(attributes, attributes.values()),
                             iter(line_attributes.items()))
    assert list(lines.attributes) == list(attributes)
    assert list(lines.line_attributes) == ["seed_id"]
    for name, values in attributes.items():
        np.testing.assert_array_equal(lines.attributes[name], values)


class _Lazy:
    """An array-like whose loading fails, as a lazy xarray or netCDF variable's may."""

    def __init__(self, error):
        self.error = error

    def __array__(self, dtype=None, copy=None):
        raise self.error


@pytest.mark.parametrize("error", [KeyboardInterrupt(), MemoryError(), OSError(5, "I/O error")])
def test_an_array_that_fails_to_load_raises_its_own_error(error):
    """Each had been put down to the argument's kind: 'points: expected an array-like'."""
    kind = type(error)
    with pytest.raises(kind):
        linebake.LineSet(_Lazy(error), [0, 2])
    with pytest.raises(kind):
        linebake.LineSet(np.zeros((2, 3)), [0, 2], {"a": _Lazy(error)})
    with pytest.raises(kind):
        linebake.compare(_Lazy(error), np.zeros((16, 16, 3), np.float32))


@pytest.mark.parametrize("values, message", [
    (np.zeros((2, 3), np.complex64), "points: expected an \\(n, 3\\) array of positions, got an array of complex64"),
    (np.array([["1", "2", "3"]] * 2), "points: expected .* got an array of <U1"),
    (np.zeros((2, 3), "datetime64[s]"), "points: expected .* got an array of datetime64"),
    (np.array([[1, 2, "x"]] * 2, dtype=object), "points: expected an \\(n, 3\\) array of positions \\(ValueError"),
])
def test_values_that_are_no_numbers_are_refused(values, message):
    """NumPy had converted them with a ComplexWarning at most (text parsed, dates as seconds)."""
    with pytest.raises(TypeError, match=message):
        linebake.LineSet(values, [0, 2])


def test_booleans_are_no_positions_and_none_is_no_number():
    """A bool array had been taken as points at 0 and 1, an object array's None as NaN."""
    with pytest.raises(TypeError, match="^points: expected an \\(n, 3\\) array of positions, got an array of bool"):
        linebake.LineSet(np.ones((2, 3), bool), [0, 2])
    with pytest.raises(TypeError, match="^points: expected .*, got None at row 1, column 1; give numpy.nan"):
        linebake.LineSet(np.array([[0, 0, 0], [1, None, 1]], dtype=object), [0, 2])
    with pytest.raises(TypeError, match="^attribute 'a': expected 2 float32 values, one per point, got None at item 1"):
        linebake.LineSet(np.zeros((2, 3)), [0, 2], {"a": [1.0, None]})
    # A list mixing booleans with numbers is an integer array to NumPy: its bool is named.
    with pytest.raises(TypeError, match="^points: expected .*, got True at row 0, column 0; booleans are no numbers here"):
        linebake.LineSet([[True, 0, 1], [1, 2, 3]], [0, 2])
    # NaN given as such is kept, and an attribute of booleans reads as 0 and 1.
    kept = linebake.LineSet([[0, 0, 0], [1, np.nan, 1]], [0, 2], {"a": np.array([True, False])})
    assert np.isnan(kept.points[1, 1])
    np.testing.assert_array_equal(kept.attributes["a"], np.array([1, 0], np.float32))


def test_a_masked_array_with_masked_values_is_refused():
    points = np.ma.masked_invalid(np.array([[0, 0, 0], [1, np.nan, 1]]))
    with pytest.raises(ValueError, match="^points: a masked array with masked values"):
        linebake.LineSet(points, [0, 2])
    filled = linebake.LineSet(points.filled(np.nan), [0, 2])
    assert np.isnan(filled.points[1, 1])
    # With no value masked, its values are all there is.
    whole = linebake.LineSet(np.ma.masked_invalid(np.ones((2, 3))), [0, 2])
    np.testing.assert_array_equal(whole.points, np.ones((2, 3), np.float32))
    with pytest.raises(ValueError, match="^attribute 'a': a masked array"):
        linebake.LineSet(np.zeros((2, 3)), [0, 2], {"a": np.ma.masked_equal([0.0, 1.0], 1.0)})


def test_compare_names_a_finite_value_past_float32():
    """It had been called 'not a finite value (NaN or infinity)' after NumPy's overflow warning."""
    image = np.zeros((6, 5, 3))
    image[4, 2, 1] = 1e300
    with pytest.raises(ValueError, match=r"^compare: image: pixel \(2, 4\): 1e\+300 is outside "
                                         r"float32's range"):
        linebake.compare(image, np.zeros((6, 5, 3), np.float32))


def test_an_int_past_floats_range_is_a_value_error_naming_the_argument():
    """An object array's int that float cannot hold had been a bare OverflowError."""
    with pytest.raises(ValueError, match="^points: expected an \\(n, 3\\) array of positions"):
        linebake.LineSet([[10**400, 0, 0], [1, 0, 0]], [0, 2])
    with pytest.raises(ValueError, match="^attribute 'a': expected 2 float32 values"):
        linebake.LineSet(np.zeros((2, 3)), [0, 2], {"a": [10**400, 0]})


def test_compare_checks_the_range_of_colour_only_and_within_its_budget():
    """Alpha is dropped, so a value past float32 there is no error; a float64 image out of C order
    is copied for the range check only within the budget (the copy had been made before it)."""
    import tracemalloc
    image = np.full((16, 16, 4), 0.5)
    image[3, 5, 3] = 1e300
    assert linebake.compare(image, np.full((16, 16, 3), 0.5, np.float32))["psnr_db"] == 60.0
    big = np.asfortranarray(np.full((1500, 1500, 3), 0.5))
    reference = np.zeros((1500, 1500, 3), np.float32)
    tracemalloc.start()
    try:
        with pytest.raises(linebake.BudgetExceeded, match="^compare: image's 1500x1500 array"):
            linebake.compare(big, reference, memory_budget="1M")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 << 20, peak
