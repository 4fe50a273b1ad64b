"""Arguments as the module takes them: paths (str, bytes, os.PathLike, not UTF-8, a NUL in one),
values of the wrong kind, render's option values against the CLI's checks, integer images in
compare(), and what bake() of a LineSet names and leaves."""

import os
import pathlib
import struct
import subprocess
import threading
import zlib

import numpy as np
import pytest

import linebake
from conftest import SYNTH, cli_error, cli_json, cli_path, resident_bytes, vulkan_available

SIZE = (32, 24)


def small_lines(points=40, seed=1):
    rng = np.random.default_rng(seed)
    return linebake.LineSet(rng.normal(size=(points, 3)).cumsum(axis=0),
                            np.array([0, points // 2, points], dtype=np.uint64))


# --- paths -------------------------------------------------------------------------------------


def test_a_nul_in_a_path_is_a_value_error(tmp_path, baked):
    # The C library ends a name at its first NUL: write(ls, "w.h5\0.vtp") wrote VTP (the format
    # of the whole name) into w.h5. Every path argument refuses it, as open() does, and nothing
    # is written.
    cache, _ = baked
    lines = small_lines()
    base = str(tmp_path / "w.h5")
    calls = {
        "write": lambda: linebake.write(lines, base + "\0.vtp"),
        "read": lambda: linebake.read(base + "\0.vtp"),
        "bake": lambda: linebake.bake(base + "\0.vtp", str(tmp_path / "c.lbc.h5")),
        "bake: cache": lambda: linebake.bake(lines, str(tmp_path / "c.lbc.h5") + "\0.x"),
        "open_cache": lambda: linebake.open_cache(cache + "\0.x"),
        "render: cache": lambda: linebake.render(cache + "\0.x", technique="reference"),
        "Renderer: cache": lambda: linebake.Renderer(cache + "\0.x", "reference"),
        "render: tf": lambda: linebake.render(cache, technique="reference", size=SIZE,
                                              tf=str(tmp_path / "tf.json") + "\0semi"),
        "render: flight": lambda: linebake.render(cache, technique="reference", size=SIZE,
                                                  flight=str(tmp_path / "k.json") + "\0orbit"),
        "compare: image": lambda: linebake.compare(base + "\0.png", base + ".png"),
    }
    for name, call in calls.items():
        with pytest.raises(ValueError, match=f"^{name}: embedded null byte in "):
            call()
    assert os.listdir(tmp_path) == []


def cli_stderr_error(*args):
    """The CLI's error for arguments that may be bytes, decoded as os.fsdecode decodes."""
    result = subprocess.run([cli_path(), *args], capture_output=True)
    assert result.returncode != 0
    first = os.fsdecode(result.stderr).strip().splitlines()[0]
    assert first.startswith("linebake: error: "), first
    return first[len("linebake: error: "):]


def test_paths_that_are_not_utf8(tmp_path, baked):
    # A file name that is not UTF-8: as bytes, or as the str os.listdir and os.fsdecode give for
    # it (a surrogate escape per byte), as os.fsencode takes them. read(b"n\xff.vtp") raised
    # UnicodeDecodeError instead of "no such file", the str "Unable to cast".
    name = os.fsencode(tmp_path) + b"/n\xff.vtp"
    text = os.fsdecode(name)
    assert "\udcff" in text
    for given in (name, text, pathlib.Path(text)):
        with pytest.raises(linebake.InputError) as caught:
            linebake.read(given)
        assert str(caught.value) == cli_stderr_error(b"info", name)
        assert caught.value.file == text
    lines = small_lines()
    linebake.write(lines, name)
    assert os.listdir(tmp_path) == ["n\udcff.vtp"]
    for given in (name, text, pathlib.Path(text)):
        back = linebake.read(given)
        assert back.same_data(lines) and back.source == text
        assert text in repr(back)
    # A cache of that name (bake itself cannot make one: its provenance, JSON, holds the path,
    # which must be UTF-8, the CLI's as well): opened and rendered by the bytes or the str.
    made = tmp_path / "c.lbc.h5"
    linebake.bake(lines, made)
    cache = os.fsencode(tmp_path) + b"/c\xfe.lbc.h5"
    os.rename(made, cache)
    expected, _ = linebake.render(os.fsdecode(cache), technique="reference", size=SIZE)
    assert np.ptp(expected[..., :3]) > 0
    for given in (cache, os.fsdecode(cache), pathlib.Path(os.fsdecode(cache))):
        opened = linebake.open_cache(given)
        assert opened.path == os.fsdecode(cache) and os.fsdecode(cache) in repr(opened)
        assert opened.lines().same_data(lines)
        image, _ = linebake.render(given, technique="reference", size=SIZE)
        np.testing.assert_array_equal(image, expected)
    # Not a cache: the CLI's message, decoded alike.
    with pytest.raises(linebake.InputError) as caught:
        linebake.open_cache(name)
    assert str(caught.value) == cli_stderr_error(b"report", name)
    # A str os.fsencode cannot encode (a surrogate no byte stands for), as open() refuses it.
    with pytest.raises(ValueError, match="^read: 'utf-8' codec can't encode"):
        linebake.read(str(tmp_path / "\ud800.vtp"))


def test_render_and_compare_take_every_kind_of_path(baked, tmp_path):
    # The cache of render() and Renderer, and compare()'s files, are str, bytes or os.PathLike
    # as every path is: bytes were "b'...': no such file", a Path in compare "no such file".
    cache, _ = baked
    expected, _ = linebake.render(cache, technique="reference", size=SIZE)
    for given in (os.fsencode(cache), pathlib.Path(cache)):
        image, _ = linebake.render(given, technique="reference", size=SIZE)
        np.testing.assert_array_equal(image, expected)
        image, _ = linebake.Renderer(given, "reference", size=SIZE).render()
        np.testing.assert_array_equal(image, expected)
    for call, name in [(lambda: linebake.render(5), "render"),
                       (lambda: linebake.Renderer(5), "Renderer")]:
        with pytest.raises(TypeError, match=f"^{name}: cache: expected a str, bytes or "
                                            "os.PathLike, got 5$"):
            call()
    first, second = tmp_path / "a.pfm", tmp_path / "b.pfm"
    for path, frame in ((first, 0), (second, 3)):
        cli_json("render", cache, "--technique", "reference", "--size", "32x24", "--frame",
                 frame, "-o", path)
    theirs = cli_json("compare", first, second)
    for a, b in ((first, second), (os.fsencode(first), os.fsencode(second)),
                 (str(first), pathlib.Path(second))):
        ours = linebake.compare(a, b)
        assert (ours["psnr_db"], ours["ssim"]) == (theirs["psnr_db"], theirs["ssim"])


# --- values of the wrong kind ------------------------------------------------------------------


@pytest.mark.parametrize("value", [-1, 1.5e9, None, b"2G", 2**64, True, np.float64(2e9)],
                         ids=repr)
def test_bake_memory_budget_of_the_wrong_kind(tmp_path, value):
    # True was taken as 1 byte; the rest raised a bare RuntimeError ("Unable to cast").
    with pytest.raises(TypeError, match=r"^bake: memory_budget: expected a size str \('2G', "
                                        r"'unlimited'\) or a number of bytes"):
        linebake.bake(small_lines(), tmp_path / "m.lbc.h5", memory_budget=value)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("call", ["read", "bake"])
def test_a_bad_budget_text_is_a_usage_error_naming_the_argument(tmp_path, call):
    # It was a plain linebake.Error, "bad size 'abc' ...", naming no argument (render's named it).
    source = tmp_path / "s.h5"
    linebake.write(small_lines(), source)
    with pytest.raises(linebake.UsageError, match=rf"^{call}: memory_budget: bad size 'abc'"):
        if call == "read":
            linebake.read(source, memory_budget="abc")
        else:
            linebake.bake(small_lines(), tmp_path / "m.lbc.h5", memory_budget="abc")
    assert os.listdir(tmp_path) == ["s.h5"]


@pytest.mark.parametrize("value", [None, True, 16.7, [16, 16, 16], b"16"], ids=repr)
def test_bake_grid_of_the_wrong_kind(tmp_path, value):
    # It was str()'d: grid=None said "--grid: expected auto, N or NxNxN, got 'None'".
    with pytest.raises(TypeError, match=r"^bake: grid: expected 'auto', an integer N or a str "
                                        r"'NxNxN', got "):
        linebake.bake(small_lines(), tmp_path / "g.lbc.h5", assets=["voxels"], grid=value)


def test_bake_grid_takes_an_int_and_the_clis_text(tmp_path):
    lines = small_lines()
    source = tmp_path / "l.h5"
    linebake.write(lines, source)
    for grid, cli in ((8, "8"), ("4x5x6", "4x5x6")):
        cache = tmp_path / f"g{cli}.lbc.h5"
        linebake.bake(lines, cache, assets=["voxels"], grid=grid)
        theirs = tmp_path / f"cli{cli}.lbc.h5"
        cli_json("bake", source, "-o", theirs, "--assets", "voxels", "--grid", cli)
        assert linebake.open_cache(cache).voxels()["resolution"] == \
            linebake.open_cache(theirs).voxels()["resolution"]


@pytest.mark.parametrize("keywords, message", [
    ({"size": (16.0, 12.0)}, r"render: size: expected \(width, height\) integers or a str 'WxH'"),
    ({"size": 16}, r"render: size: expected \(width, height\) integers"),
    ({"size": (16, 12, 1)}, r"render: size: expected \(width, height\) integers"),
    ({"size": (True, 12)}, r"render: size: expected \(width, height\) integers"),
    ({"radius": "x"}, "render: radius: expected a number, got 'x'"),
    ({"radius": True}, "render: radius: expected a number, got True"),
    ({"hits": -4}, "render: hits: expected a str, got -4"),
    ({"early_termination": "yes"}, "render: early_termination: expected True or False"),
    ({"early_termination": 1}, "render: early_termination: expected True or False"),
    ({"frame": True}, "render: frame: expected an integer in range, got True"),
    ({"frame": 1.0}, "render: frame: expected an integer in range, got 1.0"),
    ({"frame_count": "64"}, "render: frame_count: expected an integer in range"),
    ({"memory_budget": True}, "render: memory_budget: expected a size str"),
    ({"memory_budget": 1.5e9}, "render: memory_budget: expected a size str"),
    ({"memory_budget": -1}, "render: memory_budget: expected a size str"),
    ({"technique": 5}, "render: technique: expected a str, got 5"),
    ({"tf": 5}, "render: tf: expected a str, bytes or os.PathLike, got 5"),
], ids=lambda v: repr(v) if isinstance(v, dict) else "")
def test_render_values_of_the_wrong_kind(baked, keywords, message):
    cache, _ = baked
    arguments = {"technique": "embree", "size": SIZE, **keywords}
    with pytest.raises(TypeError, match="^" + message):
        linebake.render(cache, **arguments)


def test_renderer_values_of_the_wrong_kind(baked):
    cache, _ = baked
    with pytest.raises(TypeError, match="^Renderer: layers: expected an integer in range, got "
                                        "4.0$"):
        linebake.Renderer(cache, "mlab", size=SIZE, layers=4.0)
    # The right kind but out of range: the CLI's message (which took -1 as 2^64 - 1 before).
    with pytest.raises(linebake.UsageError, match="^--capacity: Value -1 not in range 0 to 2"):
        linebake.Renderer(cache, "ll", size=SIZE, capacity=-1)
    renderer = linebake.Renderer(cache, "reference", size=SIZE)
    with pytest.raises(TypeError, match="^Renderer.render: frame: expected an integer"):
        renderer.render(frame=2.5)
    with pytest.raises(TypeError, match=r"^Renderer.render: size: expected \(width, height\)"):
        renderer.render(size=(16.0, 12.0))
    # Named as the call the user made (render's said "Renderer()").
    with pytest.raises(TypeError, match=r"^Renderer\(\) got an unexpected keyword argument "
                                        "'layer'; did you mean 'layers'"):
        linebake.Renderer(cache, "mlab", layer=4)
    with pytest.raises(TypeError, match=r"^render\(\) got an unexpected keyword argument 'layer'"):
        linebake.render(cache, technique="mlab", layer=4)


def test_an_int_memory_budget_is_bytes_everywhere(baked, tmp_path):
    # bake took bytes as an int, render, Renderer and read only a str ("Unable to cast"): an int
    # is bytes in all four, the same as its digits as a str.
    cache, _ = baked
    with pytest.raises(linebake.BudgetExceeded) as as_text:
        linebake.Renderer(cache, "reference", size=SIZE, memory_budget="1M")
    with pytest.raises(linebake.BudgetExceeded) as as_int:
        linebake.Renderer(cache, "reference", size=SIZE, memory_budget=1 << 20)
    assert str(as_int.value) == str(as_text.value)
    with pytest.raises(linebake.BudgetExceeded) as as_int:
        linebake.render(cache, technique="reference", size=SIZE, memory_budget=np.int64(1 << 20))
    assert str(as_int.value) == str(as_text.value)
    image, _ = linebake.render(cache, technique="reference", size=SIZE, memory_budget=1 << 40)
    np.testing.assert_array_equal(
        image, linebake.render(cache, technique="reference", size=SIZE)[0])
    points = np.arange(3 * 200000, dtype=np.float32).reshape(-1, 3)
    path = tmp_path / "big.vtk"
    linebake.write(linebake.LineSet(points, np.array([0, 200000], dtype=np.uint64)), path)
    with pytest.raises(linebake.BudgetExceeded) as as_text:
        linebake.read(path, memory_budget="1M")
    with pytest.raises(linebake.BudgetExceeded) as as_int:
        linebake.read(path, memory_budget=1 << 20)
    assert str(as_int.value) == str(as_text.value)
    with pytest.raises(TypeError, match="^read: memory_budget: expected a size str"):
        linebake.read(path, memory_budget=True)


def test_metadata_and_attribute_names_that_utf8_cannot_encode():
    # A lone surrogate (os.fsdecode's escape of a byte) is no UTF-8 text: UnicodeEncodeError
    # naming nothing, now a TypeError naming the argument.
    points = np.zeros((4, 3), np.float32) + np.arange(4)[:, None]
    with pytest.raises(TypeError, match="^metadata: keys and values are str that UTF-8 can "
                                        "encode"):
        linebake.LineSet(points, [0, 4], metadata={"a": "\udcff"})
    with pytest.raises(TypeError, match="^attribute name: expected a str"):
        linebake.LineSet(points, [0, 4], attributes={"\udcff": np.zeros(4)})
    with pytest.raises(TypeError, match="^line attribute name: expected a str, got 7"):
        linebake.LineSet(points, [0, 4], line_attributes={7: np.zeros(1)})


# --- render's option values: the CLI's checks --------------------------------------------------


OUT_OF_RANGE = [
    ("embree", {"radius": float("nan")}, ["--radius", "nan"]),
    ("embree", {"radius": -1}, ["--radius", "-1"]),
    ("embree", {"radius": 0}, ["--radius", "0"]),
    ("embree", {"radius": float("inf")}, ["--radius", "inf"]),
    ("mlab", {"layers": 0}, ["--layers", "0"]),
    ("mlab", {"layers": -3}, ["--layers", "-3"]),
    ("mlab", {"layers": 65}, ["--layers", "65"]),
    ("mlabdb", {"tau_alpha": 2.0}, ["--tau-alpha", "2.0"]),
    ("mlabdb", {"tau_opaque": -0.5}, ["--tau-opaque", "-0.5"]),
    ("mboit", {"beta": 1.5}, ["--beta", "1.5"]),
    ("mboit", {"moment_bias": 0.6}, ["--moment-bias", "0.6"]),
    ("mboit", {"moments": 5}, ["--moments", "5"]),
    ("mboit", {"moment_basis": "fourier"}, ["--moment-basis", "fourier"]),
    ("wboit", {"wboit_weight": 1}, ["--wboit-weight", "1"]),
    ("ll", {"node_bytes": 16}, ["--node-bytes", "16"]),
    ("ll", {"sort": "bubble"}, ["--sort", "bubble"]),
    ("dp", {"max_layers": 0}, ["--max-layers", "0"]),
    ("rtx", {"max_iterations": 0}, ["--max-iterations", "0"]),
    ("vrc", {"on": "tpu"}, ["--on", "tpu"]),
    ("reference", {"hits": "all"}, ["--hits", "all"]),
    ("embree", {"embree_geometry": "spline"}, ["--embree-geometry", "spline"]),
    ("tiles", {"tiles_strips": "some"}, ["--tiles-strips", "some"]),
    ("emrbee", {}, []),
    ("embree", {"size": (0, 5)}, ["--size", "0x5"]),
    ("embree", {"size": "16x"}, ["--size", "16x"]),
    ("embree", {"frame_count": 0}, ["--frame-count", "0"]),
    ("embree", {"frame": -1}, ["--frame", "-1"]),
    ("embree", {"memory_budget": 0}, ["--memory-budget", "0"]),
]


@pytest.mark.parametrize("technique, keywords, cli", OUT_OF_RANGE,
                         ids=[f"{t}-{k}" for t, k, _ in OUT_OF_RANGE])
def test_option_values_are_the_clis(baked, tmp_path, technique, keywords, cli):
    # The CLI refuses these values with a usage error; render() passed them through (radius nan
    # rendered as the default, inf a blank image, layers=-3 an absurd BudgetExceeded).
    cache, _ = baked
    arguments = {"size": SIZE, **keywords}
    size = ["--size", "32x24"] if "size" not in keywords else []
    expected = cli_error("render", cache, "--technique", technique, *size, *cli,
                         "-o", tmp_path / "x.png")
    with pytest.raises(linebake.UsageError) as caught:
        linebake.render(cache, technique=technique, **arguments)
    assert str(caught.value) == expected
    if "frame" not in keywords and "frame_count" not in keywords:
        with pytest.raises(linebake.UsageError) as caught:
            linebake.Renderer(cache, technique, **arguments)
        assert str(caught.value) == expected


@pytest.mark.parametrize("keyword, technique", [("tau_alpha", "mlabdb"), ("tau_opaque", "mlabdb"),
                                                ("beta", "mboit"), ("moment_bias", "mboit")])
def test_nan_is_out_of_a_real_range(baked, tmp_path, keyword, technique):
    # CLI::Range lets NaN through (no comparison with it is true): refused here in the message
    # the CLI gives for a value out of that range.
    cache, _ = baked
    option = "--" + keyword.replace("_", "-")
    expected = cli_error("render", cache, "--technique", technique, option, "7.0",
                         "-o", tmp_path / "x.png").replace("7.0", "nan")
    with pytest.raises(linebake.UsageError) as caught:
        linebake.render(cache, technique=technique, size=SIZE, **{keyword: float("nan")})
    assert str(caught.value) == expected


def test_values_in_range_render(baked):
    if not vulkan_available():
        pytest.skip("no Vulkan device")
    cache, _ = baked
    # The ends of the ranges pass (an int where a float is wanted too).
    linebake.render(cache, technique="mlabdb", size=SIZE, tau_alpha=0, tau_opaque=1.0, layers=64)
    linebake.render(cache, technique="mboit", size=SIZE, beta=np.float32(0.5), moments=8,
                    moment_bias=0.5)


# --- compare of integer images -----------------------------------------------------------------


def write_png(path, pixels):
    """A plain PNG (RGB, filter 0 on every row) of uint8 or uint16 pixels, big-endian words."""
    height, width, _ = pixels.shape
    depth = 16 if pixels.dtype == np.uint16 else 8
    rows = pixels.astype(">u2" if depth == 16 else "u1").reshape(height, -1).tobytes()
    stride = len(rows) // height
    raw = b"".join(b"\0" + rows[y * stride:(y + 1) * stride] for y in range(height))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, depth, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
                     chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_integer_images_compare_as_their_png(tmp_path, dtype):
    # An integer image is what a PNG of that depth holds: compare() of the arrays is `linebake
    # compare` of the PNG files. uint8 10 against 200 was compared as linear floats (60 dB,
    # SSIM 1: both clamp to white).
    rng = np.random.default_rng(5)
    top = np.iinfo(dtype).max
    first = rng.integers(0, top, size=(40, 48, 3), endpoint=True).astype(dtype)
    second = np.clip(first.astype(np.int64) + rng.integers(-top // 8, top // 8, first.shape),
                     0, top).astype(dtype)
    write_png(tmp_path / "a.png", first)
    write_png(tmp_path / "b.png", second)
    theirs = cli_json("compare", tmp_path / "a.png", tmp_path / "b.png")
    ours = linebake.compare(first, second)
    assert ours["psnr_db"] == pytest.approx(theirs["psnr_db"], rel=1e-12)
    assert ours["ssim"] == pytest.approx(theirs["ssim"], rel=1e-12)
    assert linebake.compare(tmp_path / "a.png", tmp_path / "b.png") == ours
    # With alpha, as a file's is dropped.
    alpha = np.full(first.shape[:2] + (1,), top, dtype)
    assert linebake.compare(np.concatenate([first, alpha], axis=2), second) == ours
    step = (top + 1) // 256  # 8-bit values 10 and 200 at either depth
    flat = linebake.compare(np.full((16, 16, 3), 10 * step, dtype),
                            np.full((16, 16, 3), 200 * step, dtype))
    assert flat["psnr_db"] < 30 and flat["ssim"] < 0.9


def test_integer_images_may_say_they_are_linear():
    # srgb_encoded=False: the scaled values are linear light, encoded as float images are.
    values = np.random.default_rng(6).integers(0, 256, size=(16, 16, 3))
    a, b = values.astype(np.uint8), np.roll(values, 1, axis=0).astype(np.uint8)
    ours = linebake.compare(a, b, srgb_encoded=False)
    # float32 of value / 255 in double precision, as the module scales them.
    assert ours == linebake.compare((a / 255).astype(np.float32), (b / 255).astype(np.float32))
    with pytest.raises(TypeError):
        linebake.compare(a, b, srgb_encoded=1)


def test_compare_holds_its_images_within_the_memory_budget():
    # Each image as float32 (48 MB for 2000x2000 RGB), and a copy where the array is another
    # dtype or order, reserved from what the budget leaves beside the process's resident memory
    # before anything is allocated: compare() of two 20000x20000 arrays had met the OOM killer.
    a = np.random.default_rng(7).random((2000, 2000, 3), dtype=np.float32)
    b = np.flip(a, axis=0).copy()
    mib = 1 << 20
    with pytest.raises(linebake.BudgetExceeded,
                       match=r"^compare: reference's 2000x2000 array \(12000000 values\) needs "
                             r"about 45.78 MiB"):
        linebake.compare(a, b, memory_budget=resident_bytes() + 70 * mib)
    with pytest.raises(linebake.BudgetExceeded,
                       match=r"^compare: image's 2000x2000 array \(12000000 values\) needs "
                             r"about 91.55 MiB"):  # its float64 values converted first
        linebake.compare(a.astype(np.float64), b, memory_budget=resident_bytes() + 70 * mib)
    fitted = linebake.compare(a, b, memory_budget=resident_bytes() + 130 * mib)
    assert fitted == linebake.compare(a, b, memory_budget="unlimited")
    assert 0 < fitted["ssim"] < 0.1
    with pytest.raises(linebake.UsageError, match="memory_budget"):
        linebake.compare(a, b, memory_budget="lots")


@pytest.mark.parametrize("dtype", [np.bool_, np.int8, np.int32, np.int64, np.uint32, np.uint64,
                                   np.complex64])
def test_other_dtypes_are_type_errors(dtype):
    image = np.ones((8, 8, 3), dtype=dtype)
    reference = np.ones((8, 8, 3), dtype=np.float32)
    with pytest.raises(TypeError, match=r"^compare: image: expected float, uint8 or uint16 "
                                        "values, got " + np.dtype(dtype).name):
        linebake.compare(image, reference)
    with pytest.raises(TypeError, match=r"^compare: reference: expected float"):
        linebake.compare(reference, image)


# --- bake of a LineSet: its temporary input ----------------------------------------------------


def test_threads_baking_line_sets_into_one_cache_path(tmp_path):
    # The temporary input was <cache>.input-<pid>.h5 for every thread of the process: a thread's
    # bake read another's lines (its provenance described them) or found the file gone. Each
    # call has its own now.
    cache = tmp_path / "shared.lbc.h5"
    sets = [small_lines(points=20 + 2 * k, seed=k) for k in range(6)]
    for _ in range(3):
        results, errors = [None] * len(sets), []

        def work(k):
            try:
                results[k] = linebake.bake(sets[k], cache, tube_sides=3)
            except Exception as e:  # reported below
                errors.append(repr(e))

        threads = [threading.Thread(target=work, args=(k,)) for k in range(len(sets))]
        [t.start() for t in threads]
        [t.join() for t in threads]
        assert errors == []
        for lines, result in zip(sets, results):
            stats = result["steps"][0]["provenance"]["stats"]
            assert (stats["points"], stats["lines"]) == (lines.point_count, lines.line_count)
        assert any(linebake.open_cache(cache).lines().same_data(s) for s in sets)
        assert os.listdir(tmp_path) == ["shared.lbc.h5"]


def test_bake_of_a_line_set_names_the_set_not_its_temporary_file(tmp_path):
    # Errors named the temporary input ("c.lbc.h5.input-18805.h5 (lines 0..1): invalid line
    # set"): they name the set, as the CLI names the file it bakes, "<arrays>" for arrays.
    points = np.random.default_rng(2).normal(size=(40, 3)).cumsum(axis=0)
    points[3] = np.nan
    lines = linebake.LineSet(points, np.array([0, 20, 40], dtype=np.uint64))
    source = tmp_path / "nan.h5"
    linebake.write(lines, source)
    cli = cli_error("bake", source, "-o", tmp_path / "cli.lbc.h5", "--on-invalid", "reject")
    assert cli.startswith(f"{source} (lines 0..1): invalid line set")
    with pytest.raises(linebake.InputError) as caught:
        linebake.bake(lines, tmp_path / "c.lbc.h5", on_invalid="reject")
    assert str(caught.value) == cli.replace(str(source), "<arrays>")
    assert caught.value.file == "<arrays> (lines 0..1)"
    # A set read from a file: that file, the CLI's message word for word.
    with pytest.raises(linebake.InputError) as caught:
        linebake.bake(linebake.read(source), tmp_path / "c.lbc.h5", on_invalid="reject")
    assert str(caught.value) == cli
    # What a repair did, in the result's notes.
    notes = linebake.bake(lines, tmp_path / "r.lbc.h5")["notes"]
    assert notes and all(n.startswith("<arrays>: ") for n in notes)
    # No lines.
    empty = tmp_path / "empty.h5"
    linebake.write(linebake.LineSet(np.zeros((0, 3)), [0]), empty)
    cli = cli_error("bake", empty, "-o", tmp_path / "cli.lbc.h5")
    with pytest.raises(linebake.InputError) as caught:
        linebake.bake(linebake.LineSet(np.zeros((0, 3)), [0]), tmp_path / "e.lbc.h5")
    assert str(caught.value) == cli.replace(str(empty), "<arrays>")
    assert sorted(os.listdir(tmp_path)) == ["empty.h5", "nan.h5", "r.lbc.h5"]


def test_bake_of_a_line_set_into_a_missing_directory(tmp_path):
    # The directory is the cache's: "nope/x.lbc.h5.input-13422.h5: cannot create HDF5 file"
    # named the temporary input.
    lines = small_lines()
    source = tmp_path / "l.h5"
    linebake.write(lines, source)
    cache = tmp_path / "nope" / "x.lbc.h5"
    with pytest.raises(linebake.OutputError) as caught:
        linebake.bake(lines, cache)
    assert str(caught.value) == cli_error("bake", source, "-o", cache)
    assert caught.value.file == str(cache)
    # A dry run writes nothing there (the CLI's dry run does not need the directory either):
    # the estimate is the CLI's.
    result = linebake.bake(lines, cache, dry_run=True)
    theirs = linebake.bake(source, cache, dry_run=True)
    assert result["estimate"] == theirs["estimate"] and not result["written"]
    assert result["free_bytes"] is None  # the file system could not be asked (was 2**64 - 1)
    assert os.listdir(tmp_path) == ["l.h5"]


def test_a_dry_run_leaves_nothing_beside_the_cache(tmp_path):
    seen = []
    stop = threading.Event()

    def watch():  # what appears beside the cache while the dry run runs
        while not stop.is_set():
            seen.extend(os.listdir(tmp_path))

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        for _ in range(5):
            linebake.bake(small_lines(points=4000), tmp_path / "d.lbc.h5", dry_run=True)
    finally:
        stop.set()
        watcher.join()
    assert seen == [] and os.listdir(tmp_path) == []


# --- smaller -----------------------------------------------------------------------------------


def test_camera_values(baked):
    cache, _ = baked
    renderer = linebake.Renderer(cache, "reference", size=SIZE)
    camera = {"eye": [0, 0, 5], "target": [0, 0, 0], "fov": 45}
    expected, _ = renderer.render(camera=camera)
    # NumPy scalars are numbers ("fov: expected a number, got 45.0").
    for fov in (np.float32(45), np.int64(45), 45.0):
        image, _ = renderer.render(camera={**camera, "fov": fov})
        np.testing.assert_array_equal(image, expected)
    image, _ = renderer.render(camera={**camera, "eye": np.array([0, 0, 5], np.float32)})
    np.testing.assert_array_equal(image, expected)
    with pytest.raises(TypeError, match="^camera: fov: expected a number, got True$"):
        renderer.render(camera={**camera, "fov": True})
    with pytest.raises(TypeError, match="^camera: eye: expected three numbers"):
        renderer.render(camera={**camera, "eye": [0, True, 5]})
    # An unknown key was ignored: the camera rendered at the default fov.
    with pytest.raises(ValueError, match=r"^camera: unknown key 'fovy' \(eye, target, up, fov\); "
                                         r"did you mean 'fov'\?$"):
        renderer.render(camera={"eye": [0, 0, 5], "target": [0, 0, 0], "fovy": 30})


def test_bad_names_are_usage_errors(tmp_path):
    lines = small_lines()
    # validate("bogus") was a plain Error while with_derived(["bogus"]) was a UsageError.
    with pytest.raises(linebake.UsageError, match="unknown invalid-data policy 'bogus'"):
        lines.validate("bogus")
    with pytest.raises(linebake.UsageError, match="unknown derived attribute 'bogus'"):
        lines.with_derived(["bogus"])
    for keyword, value in [("on_invalid", "bogus"), ("compression", "zip"), ("normals", "oct8"),
                           ("embree_quality", "best")]:
        assets = ["embree"] if keyword.startswith("embree") else ["tubes"]
        with pytest.raises(linebake.UsageError, match=f"unknown .*'{value}'"):
            linebake.bake(lines, tmp_path / "b.lbc.h5", assets=assets, **{keyword: value})


def test_empty_views_are_read_only():
    # Views of no points were fresh writable arrays, not read-only as every view is.
    lines = linebake.LineSet(np.zeros((0, 3)), [0])
    views = [lines.points, lines.offsets]
    with_attributes = linebake.LineSet(np.zeros((0, 3)), [0], {"t": np.zeros(0)}, {})
    views.append(with_attributes.attributes["t"])
    for array in views:
        assert not array.flags.writeable
        with pytest.raises(ValueError):
            array[...] = 0
    assert lines.points.shape == (0, 3) and lines.points.dtype == np.float32


def test_exceptions_made_in_python_have_the_attributes():
    # The stub declares them; linebake.InputError("x").file was an AttributeError.
    assert linebake.InputError("x").file is None and linebake.InputError("x").where is None
    assert linebake.OutputError("x").file is None
    assert str(linebake.InputError("x")) == "x"


# --- early termination -------------------------------------------------------------------------


def test_early_termination_false_stops_vrc_no_earlier_than_the_clis_flag(baked):
    """vrc stops early by default; early_termination=False composites every hit, as
    no_early_termination=True and the CLI's --no-early-termination do (it had been ignored)."""
    cache, _ = baked
    default, default_stats = linebake.render(cache, technique="vrc", size=SIZE)
    off, off_stats = linebake.render(cache, technique="vrc", size=SIZE, early_termination=False)
    flag, flag_stats = linebake.render(cache, technique="vrc", size=SIZE, no_early_termination=True)
    assert default_stats["early_termination"] is True
    assert off_stats["early_termination"] is False and flag_stats["early_termination"] is False
    assert np.array_equal(off, flag)
    on, on_stats = linebake.render(cache, technique="vrc", size=SIZE, early_termination=True)
    assert on_stats["early_termination"] is True and np.array_equal(on, default)


def test_early_termination_and_its_negation_exclude_each_other(baked):
    cache, _ = baked
    for technique in ["vrc", "embree"]:
        with pytest.raises(linebake.UsageError, match="exclude each other"):
            linebake.render(cache, technique=technique, size=SIZE, early_termination=True,
                            no_early_termination=True)


def test_mlabdb_needs_two_layers_a_usage_error(baked):
    if not vulkan_available():
        pytest.skip("no Vulkan device")
    cache, _ = baked
    with pytest.raises(linebake.UsageError, match="--layers: mlabdb takes 2 to 64"):
        linebake.render(cache, technique="mlabdb", size=SIZE, layers=1)


# --- bake's numbers, checked as the CLI checks them -------------------------------------------


@pytest.mark.parametrize("keywords, message", [
    ({"tube_sides": -3}, "--tube-sides: Value -3 not in range 3 to 32"),
    ({"tube_sides": 10**9}, "--tube-sides: Value 1000000000 not in range 3 to 32"),
    ({"compression": "deflate", "compression_level": 100},
     "--compression-level: Value 100 not in range 1 to 9"),
    ({"compression": "blosc-zstd", "compression_level": 0},
     "--compression-level: Value 0 not in range 1 to 9"),
    ({"radius": float("nan")}, "--radius: nan is out of range"),
], ids=repr)
def test_bake_numbers_out_of_the_clis_range(tmp_path, keywords, message):
    """They had reached the bake: a negative tube_sides as a memory estimate of 16 million TiB,
    compression_level 100 as a codec failure, -1 and blosc's 0 accepted."""
    with pytest.raises(linebake.UsageError, match=message.replace("(", r"\(")):
        linebake.bake(small_lines(), str(tmp_path / "x.lbc.h5"), **keywords)
    assert not (tmp_path / "x.lbc.h5").exists()



def test_an_empty_attribute_name_is_refused():
    """It had read back as 'unnamed' from most formats and made a CSV linebake cannot read."""
    points = np.zeros((2, 3))
    with pytest.raises(ValueError, match="attribute names must not be empty"):
        linebake.LineSet(points, [0, 2], {"": np.zeros(2)})
    with pytest.raises(ValueError, match="line attribute names must not be empty"):
        linebake.LineSet(points, [0, 2], line_attributes={"": np.zeros(1)})


def test_write_options_are_checked_as_convert_checks_them(tmp_path):
    """An unknown vtp_encoding or binlines_version had been a plain Error, after the warnings."""
    lines = small_lines()
    with pytest.raises(linebake.UsageError, match="vtp_encoding: .*'nope'"):
        linebake.write(lines, str(tmp_path / "x.vtp"), vtp_encoding="nope")
    with pytest.raises(linebake.UsageError, match="binlines_version: 1 or 2, not 9"):
        linebake.write(lines, str(tmp_path / "x.binlines"), binlines_version=9)
    # Another format's options are refused, as convert refuses them (they had been ignored).
    with pytest.raises(linebake.UsageError, match="^write: ascii: only for vtk and vtp outputs"):
        linebake.write(lines, str(tmp_path / "x.h5"), ascii=True)
    with pytest.raises(linebake.UsageError, match="^write: binlines_version: only for binlines"):
        linebake.write(lines, str(tmp_path / "x.vtk"), binlines_version=1)
    with pytest.raises(linebake.UsageError, match="^write: vtp_encoding and vtp_compress: only"):
        linebake.write(lines, str(tmp_path / "x.csv"), vtp_compress=False)
    assert not list(tmp_path.iterdir())
    linebake.write(lines, str(tmp_path / "x.vtk"), ascii=True)
    linebake.write(lines, str(tmp_path / "x.binlines"), binlines_version=1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.binlines", "x.vtk"]


@pytest.mark.parametrize("call, message", [
    (lambda p: linebake.write(small_lines(), p, ascii=1.5), "^write: ascii: expected True or False, got 1.5"),
    (lambda p: linebake.write(small_lines(), p, strict=None), "^write: strict: expected True or False, got None"),
    (lambda p: linebake.write(small_lines(), p, vtp_compress=2), "^write: vtp_compress: expected True or False"),
    (lambda p: linebake.write(small_lines(), p, binlines_version=True), "^write: binlines_version: expected an integer"),
    (lambda p: linebake.write(small_lines(), p, binlines_version=2.0), "^write: binlines_version: expected an integer"),
    (lambda p: linebake.write(small_lines(), p, vtp_encoding=None), "^write: vtp_encoding: expected a str, got None"),
    (lambda p: linebake.write(small_lines(), p, format=3), "^write: format: expected a str, got 3"),
    (lambda p: linebake.read(SYNTH, 3), "^read: format: expected a str, got 3"),
    (lambda p: linebake.bake(small_lines(), p, progress=1.5), "^bake: progress: expected True or False, got 1.5"),
    (lambda p: linebake.bake(small_lines(), p, assets="tubes"), "^bake: assets: expected a list of str, got 'tubes'"),
    (lambda p: linebake.bake(small_lines(), p, assets=["tubes", 1]), "^bake: assets: expected a str, got 1"),
    (lambda p: linebake.compare(np.zeros((16, 16, 3)), np.zeros((16, 16, 3)), srgb_encoded=1),
     "^compare: srgb_encoded: expected True or False, got 1"),
    (lambda p: linebake.techniques(None), "^techniques: device: expected a str, got None"),
    (lambda p: small_lines().with_derived("curvature"), "^with_derived: names: expected a list of str"),
    (lambda p: small_lines().validate(None), "^validate: policy: expected a str, got None"),
])
def test_arguments_of_the_wrong_kind_are_named(tmp_path, call, message):
    """A number had been taken as a flag (progress=1.5, ascii=nan), True as binlines version 1,
    and the rest had been pybind11's 'incompatible function arguments', naming no argument."""
    with pytest.raises(TypeError, match=message.replace("(", r"\(")):
        call(str(tmp_path / "x.vtk"))
    assert not list(tmp_path.iterdir())


def test_an_iterable_of_assets_is_taken(tmp_path):
    report = linebake.bake(small_lines(), str(tmp_path / "x.lbc.h5"),
                           assets=(a for a in ["tubes"]))
    assert [s["step"] for s in report["steps"] if s["step"] != "lines"] == ["tubes"]


@pytest.mark.parametrize("call, what", [
    (lambda: linebake.LineSet(np.zeros((2, 3)), [0, 2], {"a\0b": np.zeros(2)}), "attribute name"),
    (lambda: linebake.LineSet(np.zeros((2, 3)), [0, 2], metadata={"k": "v\0w"}), "metadata"),
    (lambda: linebake.techniques("0\0"), "techniques: device"),
    (lambda: linebake.read(SYNTH, memory_budget="1G\0x"), "read: memory_budget"),
])
def test_text_with_a_null_byte_is_refused(call, what):
    """The C library ends text at a NUL: an attribute name had been written cut short to HDF5
    ('a') and as U+FFFD to VTP, a provenance step read as the one before it."""
    with pytest.raises(ValueError, match=f"^{what}: embedded null byte in "):
        call()


def test_a_provenance_step_with_a_null_byte_is_refused(baked):
    cache = linebake.open_cache(baked[0])
    assert cache.provenance("tubes")["step"] == "tubes"
    with pytest.raises(ValueError, match="^provenance: step: embedded null byte"):
        cache.provenance("tubes\0x")
    with pytest.raises(TypeError, match="^provenance: step: expected a str, got None"):
        cache.provenance(None)


def test_an_attribute_range_past_float32_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match=r"^bake: attribute_range: .*1e\+300 is outside float32"):
        linebake.bake(small_lines(), str(tmp_path / "x.lbc.h5"), attribute_range=(-1, 1e300))
    assert not list(tmp_path.iterdir())
