#!/usr/bin/env python3
"""Air-parcel trajectories from xarray to a rendered figure: xarray -> linebake.LineSet -> bake
-> render -> matplotlib PNG.

    PYTHONPATH=build/release/python python3 examples/python/trajectories.py out/trajectories.png
"""

import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

import linebake  # noqa: E402


def parcel_trajectories(count=40, steps=120, seed=1):
    """Parcels rising in a cyclone: a CF trajectory dataset (trajectory x obs), as a model's
    post-processing would hand it over. Some parcels leave the domain early (NaN after)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, steps)
    radius = rng.uniform(2, 10, count)[:, None] * (1 - 0.5 * t)
    angle = rng.uniform(0, 2 * np.pi, count)[:, None] + 6 * t
    lon = 10 + radius * np.cos(angle)
    lat = 50 + 0.6 * radius * np.sin(angle)
    alt = 1000 + rng.uniform(3000, 8000, count)[:, None] * t**2
    temperature = 288 - 0.0065 * alt
    for parcel, end in enumerate(rng.integers(steps // 2, steps + 1, count)):
        for array in (lon, lat, alt, temperature):
            array[parcel, end:] = np.nan
    dims = ("trajectory", "obs")
    return xr.Dataset(
        {"lon": (dims, lon, {"standard_name": "longitude"}),
         "lat": (dims, lat, {"standard_name": "latitude"}),
         "alt": (dims, alt / 1000, {"standard_name": "altitude", "units": "km"}),
         "temperature": (dims, temperature, {"units": "K"})},
        attrs={"featureType": "trajectory"})


def to_line_set(ds):
    """One line per trajectory, its valid observations in order."""
    valid = np.isfinite(ds.lon.values)
    points = np.stack([ds.lon.values[valid], ds.lat.values[valid], ds.alt.values[valid]], axis=1)
    offsets = np.concatenate([[0], np.cumsum(valid.sum(axis=1))]).astype(np.uint64)
    return linebake.LineSet(points, offsets,
                            {"temperature": ds.temperature.values[valid]},
                            metadata={"source": "examples/python/trajectories.py"})


def srgb(linear):
    """Display encoding of the renderer's linear RGB."""
    linear = np.clip(linear, 0, 1)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)


def main(output):
    lines = to_line_set(parcel_trajectories())
    print(lines, lines.info()["segments"], "segments")
    # Vulkan's per-pixel linked lists where a device exists, else the exact CPU ray tracer.
    available = {t["name"] for t in linebake.techniques() if t["available"]}
    technique = "ll" if "ll" in available else "reference"
    with tempfile.TemporaryDirectory() as work:
        cache = os.path.join(work, "trajectories.lbc.h5")
        report = linebake.bake(lines, cache, assets=["tubes"], tube_sides=8, radius=0.004)
        image, stats = linebake.render(cache, technique=technique, tf="semi", size=(640, 400),
                                       frame=8)
    figure, axes = plt.subplots(figsize=(6.4, 4.4), dpi=100)
    axes.imshow(srgb(image[..., :3]))
    axes.set_axis_off()
    tubes = report["report"]["assets"]["tubes"]["stats"]
    axes.set_title(f"{lines.line_count} trajectories, {tubes['triangles']} triangles, "
                   f"{technique} in {stats['frames'][0]['seconds']:.2f} s")
    figure.savefig(output, bbox_inches="tight")
    print("wrote", output)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "trajectories.png")
