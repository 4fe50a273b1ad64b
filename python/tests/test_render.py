"""render() against `linebake render -o x.pfm` for the same cache, camera, frame and size;
compare() against `linebake compare --json`; the CLI's availability check."""

import types

import numpy as np
import pytest

import linebake
from conftest import cli_error, cli_json, read_pfm, run_cli, vulkan_available

SIZE = (96, 64)
FRAME = 12


def cli_render(cache, technique, output):
    run_cli("render", cache, "--technique", technique, "--tf", "semi", "--frame", FRAME,
            "--size", f"{SIZE[0]}x{SIZE[1]}", "-o", output)
    return read_pfm(output)


def render(cache, technique):
    return linebake.render(cache, technique=technique, tf="semi", size=SIZE, frame=FRAME)


@pytest.mark.parametrize("technique", ["reference", "ll"])
def test_render_equals_the_clis(baked, tmp_path, technique):
    if technique == "ll" and not vulkan_available():
        pytest.skip("no Vulkan device (lavapipe: mesa-vulkan-drivers)")
    cache, _ = baked
    image, stats = render(cache, technique)
    assert image.shape == (SIZE[1], SIZE[0], 4) and image.dtype == np.float32
    np.testing.assert_array_equal(image[..., 3], 1)
    expected = cli_render(cache, technique, str(tmp_path / f"{technique}.pfm"))
    np.testing.assert_array_equal(image[..., :3], expected)
    assert stats["technique"] == technique
    assert stats["frames"][0]["frame"] == FRAME
    assert stats["frames"][0]["size"] == list(SIZE)
    # Not a blank frame: the aneurysm is in view.
    assert np.ptp(image[..., :3]) > 0.1


def test_compare_equals_the_clis(baked, tmp_path):
    if not vulkan_available():
        pytest.skip("no Vulkan device")
    cache, _ = baked
    reference, _ = render(cache, "reference")
    ll, _ = render(cache, "ll")
    ours = linebake.compare(ll, reference)
    cli_render(cache, "reference", str(tmp_path / "r.pfm"))
    cli_render(cache, "ll", str(tmp_path / "l.pfm"))
    theirs = cli_json("compare", tmp_path / "l.pfm", tmp_path / "r.pfm")
    assert ours["psnr_db"] == pytest.approx(theirs["psnr_db"], rel=1e-12)
    assert ours["ssim"] == pytest.approx(theirs["ssim"], rel=1e-12)
    # Files compare as arrays do.
    assert linebake.compare(str(tmp_path / "l.pfm"), str(tmp_path / "r.pfm")) == ours
    # Identical images: the 60 dB cap and SSIM 1.
    same = linebake.compare(reference, reference)
    assert same["psnr_db"] == 60 and same["ssim"] == pytest.approx(1)
    # A NaN is not a value to compare (it made any image "identical", 60 dB): named by pixel.
    broken = np.array(reference[..., :3], dtype=np.float32)
    broken[3, 5, 1] = np.nan
    with pytest.raises(ValueError, match=r"the image's pixel \(5, 3\) is not a finite value"):
        linebake.compare(broken, reference)
    # An infinity too (the display encoding would clamp it to 1 and measure it).
    broken[3, 5, 1] = 0
    broken[7, 2, 0] = np.inf
    with pytest.raises(ValueError, match=r"the reference's pixel \(2, 7\) is not a finite"):
        linebake.compare(reference, broken)


def test_compare_grey_and_small_images_as_the_cli():
    # Grey arrays ((h, w) or (h, w, 1), as a grey PNG reads) compare with grey; against colour,
    # or under 11x11, the CLI's messages.
    rng = np.random.default_rng(5)
    grey = rng.random((16, 20), dtype=np.float32)
    other = np.clip(grey + 0.01, 0, 1)
    assert linebake.compare(grey, grey)["psnr_db"] == 60
    assert linebake.compare(grey[..., None], other[..., None]) == linebake.compare(grey, other)
    colour = np.repeat(grey[..., None], 3, axis=2)
    with pytest.raises(linebake.Error, match=r"^1 channel \(grey\), but the reference has 3 "
                                             r"channels: images of one kind compare"):
        linebake.compare(grey, colour)
    with pytest.raises(linebake.Error, match=r"^5x5: SSIM needs images of at least 11x11"):
        linebake.compare(grey[:5, :5], grey[:5, :5])


def test_renderer_reuses_its_scene(baked):
    cache, _ = baked
    renderer = linebake.Renderer(linebake.open_cache(cache), "reference", size=SIZE)
    first, _ = renderer.render(frame=FRAME)
    again, _ = renderer.render(frame=FRAME)
    np.testing.assert_array_equal(first, again)
    image, stats = renderer.render(camera={"eye": [0, 0, 5], "target": [0, 0, 0], "fov": 30})
    assert stats["frames"][0]["camera"]["eye"] == [0, 0, 5]
    # Any mapping is a camera (the stub's Mapping): the same image.
    proxied, _ = renderer.render(camera=types.MappingProxyType(
        {"eye": [0, 0, 5], "target": [0, 0, 0], "fov": 30}))
    np.testing.assert_array_equal(proxied, image)
    # A camera no renderer can use is a ValueError naming why (Embree aborted the process on
    # the NaN rays of an eye on its target).
    for camera, why in [({"eye": [0, 0, 0], "target": [0, 0, 0]}, "the eye is on the target"),
                        ({"eye": [0, 0, float("nan")], "target": [0, 0, 0]}, "finite"),
                        ({"eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 0, 1]},
                         "along the view direction"),
                        ({"eye": [0, 0, 5], "target": [0, 0, 0], "fov": 180}, "fov")]:
        with pytest.raises(ValueError, match=why):
            renderer.render(camera=camera)
    # Values of the wrong kind name the key.
    for camera, why in [({"eye": "abc", "target": [0, 0, 0]}, "camera: eye: expected three"),
                        ({"eye": [0, 0], "target": [0, 0, 0]}, "camera: eye: expected three"),
                        ({"eye": [0, 0, 5], "target": [0, 0, 0], "fov": "x"},
                         "camera: fov: expected a number")]:
        with pytest.raises(TypeError, match=why):
            renderer.render(camera=camera)


def test_availability_is_the_clis(baked):
    cache, _ = baked
    ours = {t["name"]: (t["available"], t["unavailable_reason"]) for t in linebake.techniques()}
    theirs = {t["name"]: (t["available"], t["unavailable_reason"])
              for t in cli_json("techniques")}
    assert ours == theirs
    for name, (available, reason) in ours.items():
        if not available:
            with pytest.raises(linebake.Error, match="cannot run here"):
                linebake.render(cache, technique=name, size=SIZE)


def test_tiles_strips_change_no_pixel(baked):
    if not vulkan_available():
        pytest.skip("no Vulkan device")
    cache, _ = baked
    whole, stats = linebake.render(cache, technique="tiles", tf="semi", size=SIZE, frame=FRAME)
    strips, strip_stats = linebake.render(cache, technique="tiles", tf="semi", size=SIZE,
                                          frame=FRAME, tiles_strips="all")
    np.testing.assert_array_equal(strips, whole)
    workgroups = stats["frames"][0]["composite_workgroups"]
    assert workgroups >= 24 and strip_stats["frames"][0]["composite_workgroups"] == 4 * workgroups
    # The CLI's check and message (test_arguments.py compares it with the CLI's).
    with pytest.raises(linebake.UsageError, match=r"^--tiles-strips: unknown 'some' \(none, "
                                                  r"crowded, all\)"):
        linebake.render(cache, technique="tiles", size=SIZE, tiles_strips="some")


def test_technique_options_are_checked_as_the_cli_does(baked, tmp_path):
    cache, _ = baked
    with pytest.raises(linebake.UsageError) as caught:
        linebake.render(cache, technique="reference", size=SIZE, layers=4)
    expected = cli_error("render", cache, "--technique", "reference", "--size", "96x64",
                         "--layers", 4, "-o", tmp_path / "x.png")
    assert str(caught.value) == expected
    with pytest.raises(TypeError):
        linebake.render(cache, technique="reference", colour="red")


def test_render_needs_a_cache(tmp_path):
    with pytest.raises(linebake.InputError) as caught:
        linebake.render("synth:aneurysm?scale=0.01", technique="reference")
    assert str(caught.value) == cli_error("render", "synth:aneurysm?scale=0.01", "-o",
                                          tmp_path / "x.png")


def test_the_scene_is_built_within_the_memory_budget(baked, tmp_path):
    cache, _ = baked
    # No room for the tube mesh: refused before it is read, as the CLI refuses it.
    with pytest.raises(linebake.BudgetExceeded) as caught:
        linebake.render(cache, technique="reference", size=(16, 16), memory_budget="1M")
    expected = cli_error("render", cache, "--technique", "reference", "--size", "16x16",
                         "--memory-budget", "1M", "-o", tmp_path / "x.png")
    assert str(caught.value) == expected
    assert "the tube mesh's buffers take" in expected
    with pytest.raises(linebake.BudgetExceeded):
        linebake.Renderer(cache, "embree", size=(16, 16), memory_budget="1M")
    # The Vulkan techniques read the mesh a chunk at a time, each only if it fits.
    with pytest.raises(linebake.BudgetExceeded) as caught:
        linebake.Renderer(cache, "ll", size=(16, 16), memory_budget="1M")
    assert str(caught.value).startswith("ll: the tube mesh's buffers of chunk 0 ")
    assert "more than the memory budget leaves" in str(caught.value)
    assert "of 1.00 MiB, less what the process holds already); raise --memory-budget" in \
        str(caught.value)
    # Unlimited: the same frame as under the default budget.
    unlimited, _ = linebake.render(cache, technique="reference", size=SIZE, frame=FRAME,
                                   memory_budget="unlimited")
    np.testing.assert_array_equal(unlimited, render(cache, "reference")[0])
