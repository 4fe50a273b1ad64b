"""bake() and open_cache() against the CLI's `report --json` of the same cache, and the cached
arrays against figures computed here from the line set."""

import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import linebake
from conftest import SYNTH, cli_error, cli_json


def address(array):
    return array.__array_interface__["data"][0]


def test_bake_report_is_the_clis(baked):
    cache, result = baked
    assert result["written"] and result["cache"] == cache
    assert [s["step"] for s in result["steps"]] == ["lines", "tubes", "voxels"]
    assert all(s["built"] for s in result["steps"])
    assert result["report"] == cli_json("report", cache)[0]
    assert linebake.open_cache(cache).report() == result["report"]


def test_rebake_reuses_every_step(baked):
    cache, _ = baked
    again = linebake.bake(SYNTH, cache, assets=["tubes", "voxels"], compression="none")
    assert not again["written"]
    assert not any(s["built"] for s in again["steps"])


def test_tubes_match_the_lines(baked):
    cache, _ = baked
    opened = linebake.open_cache(cache)
    assert opened.assets == ["tubes", "voxels"]
    tubes = opened.tubes()
    stats = opened.provenance("tubes")["stats"]
    vertices = sum(c["positions"].shape[0] for c in tubes["chunks"])
    triangles = sum(c["indices"].shape[0] for c in tubes["chunks"])
    assert (vertices, triangles) == (stats["vertices"], stats["triangles"])
    assert len(tubes["chunks"]) == stats["chunks"]
    # Hand-computed from the line set: a ring of `sides` vertices per point and 2 x sides
    # triangles per segment (no caps), for the lines and points the builder kept.
    lines = opened.lines()
    assert lines.same_data(linebake.read(SYNTH))
    sides = tubes["sides"]
    if tubes["lines_dropped"] == 0 and tubes["points_skipped"] == 0:
        assert vertices == sides * lines.point_count
        assert triangles == 2 * sides * lines.segment_count
    # Every vertex lies within a radius of the line set's bounds.
    bounds = lines.info()["bounds"]
    for chunk in tubes["chunks"]:
        assert chunk["positions"].dtype == np.float32 and chunk["indices"].dtype == np.uint32
        assert np.all(chunk["positions"] >= np.array(bounds["min"]) - 1.01 * tubes["radius"])
        assert np.all(chunk["positions"] <= np.array(bounds["max"]) + 1.01 * tubes["radius"])
        assert chunk["indices"].max() < chunk["positions"].shape[0]
        normals = chunk["normals"].astype(np.float64)
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1, atol=1e-5)


def test_cached_arrays_are_views(baked):
    cache, _ = baked
    opened = linebake.open_cache(cache)
    first = opened.tubes()["chunks"][0]["positions"]
    second = opened.tubes()["chunks"][0]["positions"]
    assert address(first) == address(second)
    assert not first.flags.writeable
    # The view outlives the Cache object: it holds the mapping.
    expected = np.array(first)
    del opened
    np.testing.assert_array_equal(first, expected)


def test_threads_loading_at_once_share_one_load(baked):
    # Eight threads asking a fresh Cache for its tubes and voxels at once: one load each, the
    # same memory for all (two threads assigning the lazily loaded mesh crashed).
    cache, _ = baked
    for _ in range(3):
        opened = linebake.open_cache(cache)
        with ThreadPoolExecutor(8) as pool:
            tubes = list(pool.map(lambda _: opened.tubes()["chunks"][0]["positions"], range(8)))
            voxels = list(pool.map(lambda _: opened.voxels()["offsets"], range(8)))
        assert len({address(a) for a in tubes}) == 1
        assert len({address(a) for a in voxels}) == 1


def test_voxels_match_provenance(baked):
    cache, _ = baked
    opened = linebake.open_cache(cache)
    grid = opened.voxels()
    stats = opened.provenance("voxels")["stats"]
    nx, ny, nz = grid["resolution"]
    assert list(grid["resolution"]) == stats["resolution"]
    assert grid["offsets"].shape == (nx * ny * nz + 1,)
    assert grid["chords"].shape == (stats["chords"], 2)
    assert int(grid["offsets"][-1]) == stats["chords"]
    assert grid["line_counts"].shape == (nz, ny, nx)
    # A voxel is occupied when it holds chords.
    assert int(np.count_nonzero(np.diff(grid["offsets"].astype(np.int64)))) == \
        stats["voxels_occupied"]
    assert grid["density"][0].shape == (nz, ny, nx)


def test_bake_a_line_set_from_arrays(tmp_path):
    rng = np.random.default_rng(3)
    points = np.cumsum(rng.normal(size=(40, 3)), axis=0).astype(np.float32)
    offsets = np.array([0, 10, 25, 40], dtype=np.uint64)
    lines = linebake.LineSet(points, offsets, {"t": np.arange(40, dtype=np.float32)})
    cache = str(tmp_path / "arrays.lbc.h5")
    result = linebake.bake(lines, cache, tube_sides=4)
    assert result["report"] == cli_json("report", cache)[0]
    opened = linebake.open_cache(cache)
    assert opened.lines().same_data(lines)
    tubes = opened.tubes()
    assert tubes["sides"] == 4 and tubes["attribute"] == "t"
    assert sum(c["positions"].shape[0] for c in tubes["chunks"]) == 4 * 40
    # The temporary input file is gone, and the cache does not name it: arrays have no source;
    # a set read from a file records that file.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arrays.lbc.h5"]
    assert "source" not in opened.lines().metadata
    assert opened.provenance("lines")["parameters"]["source"] == ""
    named = str(tmp_path / "named.binlines")
    linebake.write(lines, named)
    linebake.bake(linebake.read(named), str(tmp_path / "named.lbc.h5"))
    from_file = linebake.open_cache(str(tmp_path / "named.lbc.h5"))
    assert from_file.lines().metadata["source"] == named
    assert from_file.provenance("lines")["parameters"]["source"] == named
    (tmp_path / "named.lbc.h5").unlink()
    (tmp_path / "named.binlines").unlink()
    # A set read from a file never replaces it: not baked over it, not written over the cache
    # it came from.
    before = (tmp_path / "arrays.lbc.h5").read_bytes()
    from_cache = opened.lines()
    assert from_cache.source == cache
    with pytest.raises(linebake.OutputError, match="never replaces its input"):
        linebake.write(from_cache, cache, format="hdf5")
    source = str(tmp_path / "source.h5")
    linebake.write(lines, source)
    read_back = linebake.read(source)
    with pytest.raises(linebake.OutputError, match="never replaces its input"):
        linebake.bake(read_back, source, force=True)
    assert (tmp_path / "arrays.lbc.h5").read_bytes() == before
    assert linebake.read(source).same_data(lines)


def test_bake_options_are_checked(tmp_path):
    cache = str(tmp_path / "x.lbc.h5")
    with pytest.raises(TypeError, match="tube_side"):
        linebake.bake(SYNTH, cache, tube_side=4)
    with pytest.raises(linebake.UsageError, match="grid: read only when voxels are built"):
        linebake.bake(SYNTH, cache, grid=64)
    with pytest.raises(linebake.Error):
        linebake.bake(SYNTH, cache, assets=["tubes", "meshes"])
    # A value of the wrong kind names the keyword and what it wanted (pybind11 named neither).
    for keywords, wanted in [({"tube_sides": "8"}, "tube_sides: expected an integer"),
                             ({"tube_sides": 8.5}, "tube_sides: expected an integer"),
                             ({"chunk_bytes": -1}, "chunk_bytes: expected a non-negative"),
                             ({"caps": "yes"}, "caps: expected True or False")]:
        with pytest.raises(TypeError, match=wanted):
            linebake.bake(SYNTH, cache, **keywords)
    # An attribute range that maps nothing (it failed only when the mesh was read back).
    for bad in [(float("nan"), 1), (float("-inf"), float("inf")), (1, 0), (5, 5)]:
        with pytest.raises(ValueError, match="attribute_range: expected two finite numbers"):
            linebake.bake(SYNTH, cache, attribute_range=bad)
    assert not (tmp_path / "x.lbc.h5").exists()


def test_open_cache_errors_are_the_clis(tmp_path):
    lines_file = tmp_path / "l.binlines"
    linebake.write(linebake.read(SYNTH), str(lines_file))
    with pytest.raises(linebake.InputError) as caught:
        linebake.open_cache(str(lines_file))
    assert str(caught.value) == cli_error("report", lines_file)
    missing = str(tmp_path / "none.lbc.h5")
    with pytest.raises(linebake.InputError) as caught:
        linebake.open_cache(missing)
    assert str(caught.value) == cli_error("report", missing)


def test_ctrl_c_stops_a_bake_at_its_next_check(tmp_path):
    # SIGINT a second into a bake of several seconds, in the main thread of a fresh interpreter:
    # the bake stops at its next check and raises KeyboardInterrupt, leaving nothing (it used to
    # finish first, the cache written, and Python raised as the call returned); Python's own
    # handler is back afterwards.
    script = (
        "import linebake, os, signal, sys, threading, time\n"
        "start = time.time()\n"
        "threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()\n"
        "try:\n"
        "    linebake.bake('synth:convection?scale=1', sys.argv[1], assets=['tubes', 'voxels'])\n"
        "    print('finished')\n"
        "except KeyboardInterrupt as e:\n"
        "    print('interrupted', round(time.time() - start), e)\n"
        "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)\n")
    out = tmp_path / "out"
    out.mkdir()
    done = subprocess.run([sys.executable, "-c", script, str(out / "x.lbc.h5")],
                          capture_output=True, text=True, timeout=300, env=os.environ)
    lines = done.stdout.split("\n")
    assert lines[0].startswith("interrupted ") and "SIGINT" in lines[0], done.stdout + done.stderr
    assert int(lines[0].split()[1]) <= 3, lines[0]
    assert lines[1] == "True", done.stdout
    assert list(out.iterdir()) == []


def test_ctrl_c_leaves_other_threads_and_the_users_handler_alone(tmp_path):
    # A worker thread's bake and the main thread's at once: SIGINT stops neither (the worker's
    # call would see it too), and Python raises KeyboardInterrupt in the main thread once its
    # call returns. With SIGINT ignored, or a handler of the user's, a bake runs to its end and
    # the handler is Python's business. Each case says whether the signal came while its bake
    # ran (else the case proves nothing, and the test fails).
    script = (
        "import linebake, os, signal, sys, threading, time\n"
        "out = sys.argv[1]\n"
        "poked = []\n"
        "def poke(): poked.append(time.monotonic()); os.kill(os.getpid(), signal.SIGINT)\n"
        "def bake(name, scale=0.6, poke_after=None):\n"
        "    if poke_after is not None: threading.Timer(poke_after, poke).start()\n"
        "    start = time.monotonic()\n"
        "    try:\n"
        "        linebake.bake(f'synth:convection?scale={scale}', f'{out}/{name}.lbc.h5',\n"
        "                      assets=['tubes', 'voxels'])\n"
        "    finally:\n"
        "        end = time.monotonic()\n"
        "        if poke_after is not None:\n"
        "            time.sleep(0.3)\n"
        "            print(name, 'poked during the call:', start < poked[-1] < end)\n"
        "worker = threading.Thread(target=bake, args=('worker', 2.0))  # outlasts the main's\n"
        "worker.start(); time.sleep(0.2)\n"
        "try:\n"
        "    bake('main', poke_after=0.2); print('main finished')\n"
        "except KeyboardInterrupt:\n"
        "    print('main raised after its call')\n"
        "worker.join()\n"
        "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
        "bake('ignored', poke_after=0.2); print('ignored finished')\n"
        "seen = []\n"
        "signal.signal(signal.SIGINT, lambda *a: seen.append(1))\n"
        "bake('handled', poke_after=0.2); time.sleep(0.1); print('handled finished', seen)\n"
        "print(sorted(os.listdir(out)))\n")
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True,
                          text=True, timeout=300, env=os.environ)
    assert done.stdout.split("\n")[:7] == [
        "main poked during the call: True", "main raised after its call",
        "ignored poked during the call: True", "ignored finished",
        "handled poked during the call: True", "handled finished [1]",
        "['handled.lbc.h5', 'ignored.lbc.h5', 'main.lbc.h5', 'worker.lbc.h5']"], \
        done.stdout + done.stderr


def test_bake_keeps_the_lines_origin(tmp_path):
    # Far-off lines baked from a file at an origin, and from a LineSet read at one: the cache's
    # lines are relative to it, and its metadata and the /lines step say it.
    csv = tmp_path / "utm.csv"
    csv.write_text("line_id,x,y,z\n0,500000.25,5400000.07,12.5\n0,500001.5,5400000.93,13\n"
                   "0,500002.75,5400001.5,13.5\n")
    from_file = str(tmp_path / "file.lbc.h5")
    linebake.bake(str(csv), from_file, origin=(500000, 5400000, 0))
    lines = linebake.open_cache(from_file).lines()
    assert lines.origin == (500000.0, 5400000.0, 0.0)
    assert linebake.open_cache(from_file).provenance("lines")["parameters"]["origin"] == \
        "500000 5400000 0"
    assert np.array_equal(lines.points, linebake.read(csv, origin=(500000, 5400000, 0)).points)
    from_set = str(tmp_path / "set.lbc.h5")
    linebake.bake(linebake.read(csv, origin="auto"), from_set)
    assert linebake.open_cache(from_set).lines().origin == (500000.0, 5400000.0, 13.0)
    with pytest.raises(TypeError, match="origin"):
        linebake.bake(str(csv), str(tmp_path / "x.lbc.h5"), origin=[1, 2])


def test_bake_into_a_cache_keeps_its_compression_unless_asked(tmp_path):
    # A cache baked uncompressed: adding voxels without `compression` rebuilds neither /lines nor
    # the tubes for the default's sake, and writes the voxels uncompressed as well.
    csv = tmp_path / "l.csv"
    csv.write_text("line_id,x,y,z\n0,0,0,0\n0,1,0,0\n0,1,1,0\n1,0,0,1\n1,0,1,1\n")
    cache = str(tmp_path / "c.lbc.h5")
    linebake.bake(str(csv), cache, compression="none")
    added = linebake.bake(cache, assets=["tubes", "voxels"], grid=8)
    assert [(s["step"], s["built"]) for s in added["steps"]] == \
        [("lines", False), ("tubes", False), ("voxels", True)]
    opened = linebake.open_cache(cache)
    assert [opened.provenance(s)["compression"] for s in ("lines", "tubes", "voxels")] == \
        ["none"] * 3
    linebake.bake(cache, assets=["tubes"], compression="lz4")
    assert linebake.open_cache(cache).provenance("lines")["compression"] == "lz4"


INTERRUPT_SCRIPT = """
import linebake, os, signal, sys, threading, time
def timed(call):
    start = time.monotonic()
    call()
    return time.monotonic() - start
def interrupted(call, after):
    # Whether the call returned, and how long after the signal it raised KeyboardInterrupt.
    sent = []
    timer = threading.Timer(after, lambda: (sent.append(time.monotonic()),
                                            os.kill(os.getpid(), signal.SIGINT)))
    timer.start()
    returned = False
    try:
        call()
        returned = True
        timer.join()
        time.sleep(0.1)  # a signal after the call lands here
    except KeyboardInterrupt:
        pass
    return returned, None if returned else time.monotonic() - sent[0]
what, path = sys.argv[1], sys.argv[2]
if what == "read":
    call = lambda: linebake.read("synth:aneurysm?scale=1")
elif what == "renderer":
    linebake.bake("synth:aneurysm?scale=0.3", path, assets=["tubes"])
    cache = linebake.open_cache(path)
    call = lambda: linebake.Renderer(cache, "reference", (64, 48))
else:
    lines = linebake.read("synth:aneurysm?scale=1")
    call = lambda: linebake.write(lines, path)
whole = timed(call)
if what == "write":
    os.remove(path)
returned, late = interrupted(call, 0.2 * whole)
print(whole, returned, late, os.path.exists(path))
"""


@pytest.mark.parametrize("what", ["read", "renderer", "write"])
def test_ctrl_c_stops_within_a_step(tmp_path, what):
    """SIGINT a fifth into a call: a synthetic source stops between lines and an Embree build
    through its progress monitor (each had stopped about when it would have ended), and a write
    leaves nothing (an HDF5 write had finished, renamed its file into place and then raised
    KeyboardInterrupt)."""
    out = tmp_path / ("x.h5" if what == "write" else "x.lbc.h5")
    done = subprocess.run([sys.executable, "-c", INTERRUPT_SCRIPT, what, str(out)],
                          capture_output=True, text=True, timeout=300, env=os.environ)
    assert done.returncode == 0, done.stdout + done.stderr
    whole, returned, late, exists = done.stdout.split()
    if what == "write":
        # Interrupted and nothing there, or (a write faster than the timer) returned and whole.
        assert exists == returned, done.stdout
        assert [p.name for p in tmp_path.iterdir()] == ([out.name] if exists == "True" else [])
    else:
        assert returned == "False", done.stdout
        assert float(late) < 0.25 * float(whole), done.stdout
