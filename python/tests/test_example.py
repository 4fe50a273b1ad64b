"""examples/python/trajectories.py runs and writes a figure with the rendered lines in it."""

import os
import subprocess
import sys

import numpy as np
import pytest

EXAMPLE = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "python",
                       "trajectories.py")


def test_trajectories_example(tmp_path):
    pytest.importorskip("xarray")
    image = pytest.importorskip("matplotlib.image")
    output = tmp_path / "figure.png"
    subprocess.run([sys.executable, EXAMPLE, str(output)], check=True, env=os.environ.copy())
    pixels = image.imread(str(output))
    assert pixels.ndim == 3 and pixels.shape[0] > 100 and pixels.shape[1] > 100
    # More than a background: the tubes put many distinct colours in the figure.
    colours = np.unique((pixels[..., :3] * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50
