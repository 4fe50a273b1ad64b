"""Shared fixtures: the CLI binary of the same build (the independent side of every comparison),
lavapipe for the Vulkan techniques, and one small baked cache."""

import glob
import json
import os
import subprocess
import sys

import pytest

# The Vulkan loader reads VK_ICD_FILENAMES when the first instance is made: set it before
# linebake renders anything. CTest sets it; a plain `pytest` run finds lavapipe itself.
if "VK_ICD_FILENAMES" not in os.environ:
    icds = sorted(glob.glob("/usr/share/vulkan/icd.d/lvp_icd*.json"))
    if icds:
        os.environ["VK_ICD_FILENAMES"] = icds[0]

import linebake  # noqa: E402  (after the environment above)

SYNTH = "synth:aneurysm?scale=0.01"


def resident_bytes():
    """This process's resident memory, as a memory budget counts it at its start."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def cli_path():
    """The linebake binary beside the module: <build>/tools/linebake, or $LINEBAKE_CLI."""
    if os.environ.get("LINEBAKE_CLI"):
        return os.environ["LINEBAKE_CLI"]
    build = os.path.dirname(os.path.dirname(os.path.abspath(linebake.__file__)))
    return os.path.join(build, "tools", "linebake")


def run_cli(*args, check=True):
    result = subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)
    if check and result.returncode != 0:
        raise AssertionError(f"linebake {' '.join(map(str, args))}: {result.stderr}")
    return result


def cli_json(*args):
    return json.loads(run_cli(*args, "--json").stdout)


def cli_error(*args):
    """The message the CLI prints for an error: stderr without 'linebake: error: '."""
    result = run_cli(*args, check=False)
    assert result.returncode != 0, f"linebake {args} succeeded"
    first = result.stderr.strip().splitlines()[0]
    prefix = "linebake: error: "
    assert first.startswith(prefix), result.stderr
    return first[len(prefix):]


@pytest.fixture(scope="session")
def baked(tmp_path_factory):
    """synth:aneurysm at 1 %: tubes and voxels, uncompressed (so the arrays map the file)."""
    cache = str(tmp_path_factory.mktemp("cache") / "aneurysm.lbc.h5")
    result = linebake.bake(SYNTH, cache, assets=["tubes", "voxels"], compression="none")
    return cache, result


def vulkan_available():
    return any(t["name"] == "ll" and t["available"] for t in linebake.techniques())


def read_pfm(path):
    """An independent PFM reader: 'PF' colour, scale < 0 little-endian, bottom row first."""
    import numpy as np

    with open(path, "rb") as f:
        header = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    channels = 3 if header == b"PF" else 1
    return data.reshape(height, width, channels)[::-1]


sys.path.insert(0, os.path.dirname(__file__))
