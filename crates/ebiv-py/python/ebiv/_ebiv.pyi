"""Type stubs of the extension module ``ebiv._ebiv`` (crates/ebiv-py/src/*.rs).

The public API is the pure-Python package ``ebiv``, which wraps these functions: it turns
event tuples into ``ebiv.Events``, dataset structures into ``xarray.Dataset``s and
``progress=True`` into a progress bar. Times are µs of camera time; an argument typed
``_Duration`` also takes a text with units ("10ms", "1.5s").
"""

import os
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple, TypedDict, Union, final

import numpy as np
from numpy.typing import ArrayLike, NDArray

_StrPath = Union[str, "os.PathLike[str]"]
_Duration = Union[int, str]
_Progress = Optional[Callable[[int, int], object]]

#: Events as four arrays ``(t, x, y, p)``: int64 µs, uint16 px, uint16 px, uint8 0/1.
_EventArrays = Tuple[
    NDArray[np.int64], NDArray[np.uint16], NDArray[np.uint16], NDArray[np.uint8]
]

#: One variable of a dataset: ``(name, dims, array shaped by dims, attributes)``.
_Variable = Tuple[str, Tuple[str, ...], NDArray[Any], Dict[str, Any]]

class _RawDataset(TypedDict):
    """The NetCDF output's structure: dimensions, variables and global attributes."""

    dims: List[Tuple[str, int]]
    variables: List[_Variable]
    attrs: Dict[str, Any]

class _Plan(TypedDict):
    """The plan of a run: field times, their origin, the span a field needs, the sensor size."""

    times: NDArray[np.int64]
    time_origin_us: int
    extent_us: Tuple[int, int]
    geometry: Tuple[int, int]

class _Tracks(TypedDict):
    """Particle paths: id, time (µs), position (px) and velocity (px/ms) per sample."""

    id: NDArray[np.uint64]
    t_us: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    z: NDArray[np.float64]
    u: NDArray[np.float64]
    v: NDArray[np.float64]

class _SimulationRequired(TypedDict):
    events: _EventArrays
    geometry: Tuple[int, int]
    truth: _RawDataset

class _Simulation(_SimulationRequired, total=False):
    """A simulated recording; ``tracks`` only with ``tracks=True``."""

    tracks: _Tracks

#: A field: a field file's path, or a dataset structure as ``process`` returns it.
_Field = Union[_StrPath, _RawDataset]

#: Events for ``process``: a path, or arrays ``(t, x, y, p)`` as a sequence, an object with
#: those attributes or a mapping with those keys.
_Source = Union[_StrPath, Tuple[ArrayLike, ArrayLike, ArrayLike, ArrayLike], Any]

__version__: str

#: The keywords that are reader options (``geometry``, ``format``, …), with ``_`` for ``-``.
READER_OPTIONS: List[str]

class EbivError(Exception):
    """A recording, field or scenario ebiv cannot use: damaged, empty, or not what the call needs."""

@final
class Recording:
    """An event recording opened by ``open``; nothing is read until asked for."""

    @property
    def path(self) -> Path:
        """The file's path."""
    @property
    def metadata(self) -> Dict[str, Any]:
        """Format, geometry, header entries, sensor, serial, time shift (µs) and notes."""
    @property
    def geometry(self) -> Optional[Tuple[int, int]]:
        """The sensor size ``(width, height)`` when the file states it or ``geometry=`` gave it, else ``None``."""
    @property
    def time_range(self) -> Optional[Tuple[int, int]]:
        """Earliest and latest event time stamps (µs); ``None`` without events; reads the whole file once."""
    @property
    def triggers(self) -> Dict[str, NDArray[Any]]:
        """External trigger edges: arrays ``t`` (int64 µs), ``channel`` and ``value`` (uint8)."""
    @property
    def report(self) -> Dict[str, Any]:
        """What the reader dropped or found odd over the whole file, as ``ebiv info`` reports it."""
    def read(
        self, t0: Optional[_Duration] = None, t1: Optional[_Duration] = None
    ) -> _EventArrays:
        """The events with ``t0 <= t < t1`` (``None``: from the start, to the end) as ``(t, x, y, p)``."""
    def chunks(
        self, duration: Optional[_Duration] = None, count: Optional[int] = None
    ) -> Chunks:
        """Chunks of ``duration`` (aligned to the first event) or of ``count`` events; neither: the reader's batches."""
    def __iter__(self) -> Chunks:
        """The reader's own batches, as ``chunks()``."""

@final
class Chunks:
    """An iterator over a recording's events in chunks ``(t, x, y, p)``."""

    def __iter__(self) -> Chunks:
        """The iterator itself."""
    def __next__(self) -> _EventArrays:
        """The next chunk; ``StopIteration`` at the end of the file."""

def open(path: _StrPath, **reader_options: Any) -> Recording:
    """Open an event recording; reader options (``geometry=(w, h)``, ``format``, …) as keywords."""

def index(path: _StrPath, force: bool = False, **reader_options: Any) -> Optional[Path]:
    """Build and store a RAW recording's index when missing or stale (or ``force``); ``None`` for formats without one."""

def duration_us(name: str, value: _Duration) -> int:
    """A time in µs from an integer or a text with units; a ``ValueError`` names ``name``."""

def process(
    source: _Source,
    method: Optional[str] = None,
    progress: _Progress = None,
    shard: bool = False,
    **settings: Any,
) -> _RawDataset:
    """Velocity fields of a recording or event arrays with ``ebiv process``'s settings as keywords
    (``shard=True``: fields without events are gaps even when all are)."""

def filter(  # noqa: A001 (as ebiv filter)
    source: _Source, output: Optional[_StrPath] = None, **settings: Any
) -> Dict[str, Any]:
    """Denoise a recording or event arrays (``denoise="all"``, ``denoise_dt="2ms"``, …):
    counts per filter, and ``events`` (t, x, y, p) when no ``output`` is written."""

def plan(source: _StrPath, method: Optional[str] = None, **settings: Any) -> _Plan:
    """The field times and extent of a ``process`` run over ``source``, without measuring."""

def piv(
    *images: Union[_StrPath, ArrayLike],
    progress: _Progress = None,
    **settings: Any,
) -> _RawDataset:
    """Cross-correlation PIV of images (paths or 2-D arrays) with the settings of ``--method piv``."""

def simulate(
    scenario: Union[str, _StrPath],
    seed: Optional[int] = None,
    duration: Optional[_Duration] = None,
    tracks: bool = False,
    progress: _Progress = None,
) -> _Simulation:
    """A simulated recording (example name, scenario file or TOML text) with its ground truth."""

def assess(
    field: _Field,
    truth: Optional[_StrPath] = None,
    truth_example: Optional[str] = None,
    outlier_px: Optional[float] = None,
    outlier_floor: Optional[float] = None,
    outlier_fixed: Optional[float] = None,
    mm_per_px: Optional[float] = None,
    frame_interval: Optional[_Duration] = None,
) -> Dict[str, Any]:
    """The errors of a field against a truth file or ready scenario, as ``ebiv assess`` reports them."""

def write(field: _Field, path: _StrPath) -> None:
    """Write a field as NetCDF, CSV, NPZ, Tecplot or VTK by the extension of ``path``."""

def setting_names() -> List[Tuple[str, str, Optional[str], str]]:
    """Every setting of ``ebiv process``: ``(keyword, group, default or None, summary)``."""

def examples() -> List[Tuple[str, str]]:
    """The ready scenarios of ``simulate``: ``(name, description)``."""

#: Particle tracks: a track file (CSV; ``track`` writes .csv, .npz, .nc), or the columns
#: of ``TRACK_COLUMNS`` as a dict of 1-D arrays (``track_id``, ``t_us``, ``x``, ``y``,
#: ``u``, ``v`` needed; the others NaN when absent).
_TrackColumns = Union[_StrPath, Dict[str, ArrayLike]]

def live(
    source: str,
    method: Optional[str] = None,
    *,
    follow: bool = False,
    idle: str = "5s",
    replay: bool = False,
    speed: float = 1.0,
    every: Optional[str] = None,
    queue: int = 2,
    serve: Optional[str] = None,
    allow_remote: bool = False,
    on_field: Optional[Callable[[_RawDataset, Dict[str, Any]], Any]] = None,
    **settings: Any,
) -> Dict[str, Any]:
    """``ebiv live`` with each field handed to ``on_field``; returns the summary."""
    ...

def stats(
    field: Any,
    period: Union[int, str, None] = None,
    phases: int = 8,
    phase_origin: Union[int, str, None] = None,
    include_replaced: bool = False,
    mm_per_px: Optional[float] = None,
    output: Optional[str] = None,
    triggers: Optional[str] = None,
    trigger_polarity: str = "rising",
    trigger_channel: Optional[int] = None,
    reader_options: Optional[Dict[str, Any]] = None,
) -> _RawDataset:
    """``ebiv stats``: the statistics' dataset structure."""
    ...

def derive(
    field: Any,
    quantities: str = "all",
    mm_per_px: Optional[float] = None,
    output: Optional[str] = None,
) -> _RawDataset:
    """``ebiv derive``: the field's dataset structure with the derived quantities."""
    ...

def track(
    source: _Source,
    time: Union[str, Tuple[Optional[_Duration], Optional[_Duration]], None] = None,
    absolute_time: bool = False,
    output: Optional[_StrPath] = None,
    progress: _Progress = None,
    **settings: Any,
) -> _RawDataset:
    """Particle tracks of a recording or event arrays with ``ebiv track``'s settings as keywords
    (``progress`` counts bytes of the file); ``output`` also writes .csv, .npz or .nc."""

def bin_tracks(
    tracks: _TrackColumns,
    geometry: Tuple[int, int],
    bin: float = 16.0,
    interval: Optional[_Duration] = None,
    min_tracks: int = 3,
    attributes: List[Tuple[str, str]] = ...,
) -> _RawDataset:
    """The mean field of tracks in square bins on a sensor of ``geometry`` (``ebiv track --bin``),
    with ``attributes`` added to the field's."""

def assess_tracks(
    tracks: _TrackColumns,
    truth_tracks: Union[_StrPath, Dict[str, ArrayLike]],
    scenario: Union[str, _StrPath, None] = None,
    truth_example: Optional[str] = None,
) -> Dict[str, Any]:
    """Tracks scored against the simulator's particle paths, as ``ebiv assess --truth-tracks``
    writes them to ``tracks.json``."""

def track_setting_names() -> List[Tuple[str, str, str, str]]:
    """Every setting of ``ebiv track``: ``(keyword, kind of value, default, summary)``."""
