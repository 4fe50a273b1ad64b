"""Type hints for the linebake extension module (python/src/*.cpp)."""

from os import PathLike
from typing import Any, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

Json = Any  # dicts, lists, str, int, float, bool and None, as `--json` gives them
# A path as os.fsencode takes it: a str (surrogate escapes for bytes that are not UTF-8), bytes,
# or an os.PathLike of either. A NUL in it is a ValueError.
StrPath = Union[str, bytes, PathLike[str], PathLike[bytes]]
# A memory budget: "8G", "unlimited", or a number of bytes (not a bool).
MemoryBudget = Union[int, str]

class Error(RuntimeError):
    """Any failure linebake reports, with the CLI's message (FILE: PLACE: message)."""

class UsageError(Error):
    """Options that contradict each other or that nothing reads."""

class InputError(Error):
    """Bad or unreadable input; .file and .where name the place (None when made in Python)."""
    file: Optional[str]
    where: Optional[str]

class OutputError(Error):
    """An output that could not be written; .file names it (None when made in Python)."""
    file: Optional[str]

class BudgetExceeded(Error):
    """Work that does not fit the memory budget, refused before it starts."""

class Note(UserWarning):
    """What linebake tells besides errors: stale temporaries it removed, a wait for another process writing the same output, values a format's reader cannot read back."""

class LineSet:
    def __init__(
        self,
        points: npt.ArrayLike,
        offsets: npt.ArrayLike,
        attributes: Optional[Mapping[str, npt.ArrayLike]] = None,
        line_attributes: Optional[Mapping[str, npt.ArrayLike]] = None,
        metadata: Optional[Mapping[str, str]] = None,
        *,
        memory_budget: Optional[MemoryBudget] = None,
    ) -> None: ...
    @property
    def points(self) -> npt.NDArray[np.float32]: ...  # (n, 3), read-only view
    @property
    def offsets(self) -> npt.NDArray[np.uint64]: ...  # (lines + 1,), read-only view
    @property
    def attributes(self) -> dict[str, npt.NDArray[np.float32]]: ...
    @property
    def line_attributes(self) -> dict[str, npt.NDArray[np.float32]]: ...
    @property
    def metadata(self) -> dict[str, str]: ...
    @property
    def origin(self) -> Optional[Tuple[float, float, float]]: ...
    @property
    def source(self) -> Optional[str]: ...
    @property
    def point_count(self) -> int: ...
    @property
    def line_count(self) -> int: ...
    @property
    def segment_count(self) -> int: ...
    def __len__(self) -> int: ...
    def line(self, index: int) -> npt.NDArray[np.float32]: ...
    def info(self) -> dict[str, Json]: ...
    def validate(self, policy: str = "repair") -> Tuple["LineSet", dict[str, Json]]: ...
    def with_derived(self, names: Sequence[str]) -> "LineSet": ...
    def same_data(self, other: "LineSet") -> bool: ...

def read(
    source: StrPath,
    format: Optional[str] = None,
    *,
    memory_budget: Optional[MemoryBudget] = None,
    origin: Union[None, str, Sequence[float]] = None,
) -> LineSet: ...
def write(
    lines: LineSet,
    path: StrPath,
    format: Optional[str] = None,
    *,
    ascii: bool = False,
    binlines_version: int = 2,
    vtp_encoding: str = "appended",
    vtp_compress: bool = True,
    strict: bool = False,
) -> None: ...
def formats() -> list[dict[str, Json]]: ...
def derived_attributes() -> list[str]: ...

class Cache:
    @property
    def path(self) -> str: ...
    @property
    def assets(self) -> list[str]: ...
    def provenance(self, step: str) -> dict[str, Json]: ...
    def report(self) -> dict[str, Json]: ...
    def lines(self) -> LineSet: ...
    def tubes(self) -> dict[str, Any]: ...
    def voxels(self) -> dict[str, Any]: ...

def open_cache(path: StrPath) -> Cache: ...
def bake(
    lines_or_path: Union[LineSet, StrPath],
    cache: Optional[StrPath] = None,
    assets: Sequence[str] = ("tubes",),
    *,
    progress: bool = False,
    format: str = ...,
    on_invalid: str = ...,
    origin: Union[None, str, Sequence[float]] = ...,
    tube_sides: int = ...,
    radius: float = ...,
    radius_absolute: bool = ...,
    radius_attribute: str = ...,
    caps: bool = ...,
    normals: str = ...,
    attribute: str = ...,
    attribute_range: Tuple[float, float] = ...,
    chunk_bytes: int = ...,
    grid: Union[int, str] = ...,  # "auto", N or "NxNxN"
    quantization: int = ...,
    max_chords: int = ...,
    voxel_attribute: str = ...,
    embree_geometry: str = ...,
    embree_quality: str = ...,
    embree_compact: bool = ...,
    embree_robust: bool = ...,
    embree_max_primitives: int = ...,
    rtx_geometry: str = ...,
    rtx_no_compaction: bool = ...,
    device: str = ...,
    validation: bool = ...,
    compression: str = ...,
    compression_level: int = ...,
    memory_budget: MemoryBudget = ...,
    force: bool = ...,
    no_space_check: bool = ...,
    dry_run: bool = ...,
) -> dict[str, Json]: ...

Image = npt.NDArray[np.float32]  # (h, w, 4): linear RGB over the background, alpha 1

class Renderer:
    def __init__(
        self,
        cache: Union[Cache, StrPath],
        technique: str = "embree",
        size: Union[Tuple[int, int], str] = (1280, 720),
        *,
        memory_budget: Optional[MemoryBudget] = None,
        **options: Any,
    ) -> None: ...
    def render(
        self,
        tf: StrPath = "semi",
        camera: Optional[Mapping[str, Any]] = None,
        frame: int = 0,
        frame_count: int = 64,
        flight: StrPath = "orbit-zoom",
        size: Optional[Union[Tuple[int, int], str]] = None,
        memory_budget: Optional[MemoryBudget] = None,
    ) -> Tuple[Image, dict[str, Json]]: ...
    @property
    def bounds(self) -> dict[str, list[float]]: ...
    @property
    def stats(self) -> dict[str, Json]: ...
    @property
    def device(self) -> str: ...

def render(
    cache: Union[Cache, StrPath],
    *,
    technique: str = "embree",
    tf: StrPath = "semi",
    size: Union[Tuple[int, int], str] = (1280, 720),
    frame: int = 0,
    frame_count: int = 64,
    flight: StrPath = "orbit-zoom",
    camera: Optional[Mapping[str, Any]] = None,
    memory_budget: Optional[MemoryBudget] = None,
    **options: Any,
) -> Tuple[Image, dict[str, Json]]: ...
def compare(
    image: Union[npt.ArrayLike, StrPath],
    reference: Union[npt.ArrayLike, StrPath],
    *,
    srgb_encoded: Optional[bool] = None,  # None: float arrays linear, uint8/uint16 sRGB-encoded
    memory_budget: Optional[MemoryBudget] = None,
) -> dict[str, Json]: ...
def techniques(device: str = "") -> list[dict[str, Json]]: ...
