"""ebiv: event-based imaging velocimetry, flow fields from event cameras.

Read recordings into NumPy arrays, measure velocity fields by sum of correlation, motion
compensation or PIV (Willert & Klinner, Exp. Fluids 63:101, 2022), simulate recordings with
their ground truth, and assess fields against it. The same library as the ``ebiv`` command,
with the same setting names (``slab="10ms"``, ``window=[64, 32]``), defaults and results::

    import ebiv
    rec = ebiv.open("recording.raw")
    t, x, y, p = rec.read(0, 50_000)
    ds = ebiv.process("recording.raw", method="corrsum", slab="5ms", window=[64, 32])
    ds.u.isel(time=0).plot()

Particle tracks (``ebiv track``): ``ebiv.track`` follows single particles, ``ebiv.bin_tracks``
averages them into a field and ``ebiv.assess_tracks`` scores them against simulated paths.

Long calls release the GIL; Ctrl-C interrupts them. ``ebiv.dask`` spreads many recordings,
or long ones, over a Dask cluster.
"""

from __future__ import annotations

import os
import sys
from typing import Any, Callable, Dict, Iterator, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from . import _dataset, _ebiv
from ._ebiv import EbivError, __version__

__all__ = [
    "EbivError",
    "Events",
    "Recording",
    "Simulation",
    "assess",
    "assess_tracks",
    "bin_tracks",
    "derive",
    "examples",
    "filter",
    "index",
    "live",
    "open",
    "piv",
    "process",
    "settings",
    "simulate",
    "stats",
    "track",
    "track_settings",
    "write",
    "__version__",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Union[None, bool, Callable[[int, int], Any]]


class Events(NamedTuple):
    """Events as arrays: ``t`` (int64, µs of camera time), ``x``, ``y`` (uint16, px) and
    ``p`` (uint8: 1 ON, 0 OFF)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    p: np.ndarray

    def __repr__(self) -> str:
        if len(self.t) == 0:
            return "Events(0 events)"
        return f"Events({len(self.t)} events, t {self.t.min()}..{self.t.max()} µs)"


class Recording:
    """An event recording opened by :func:`open`. Nothing is read until asked for."""

    def __init__(self, native: Any, reader_options: Dict[str, Any]) -> None:
        self._native = native
        self._reader_options = dict(reader_options)

    @property
    def reader_options(self) -> Dict[str, Any]:
        """The reader options it was opened with; :func:`process` of the recording uses them."""
        return dict(self._reader_options)

    @property
    def path(self) -> str:
        """The file's path."""
        return str(self._native.path)

    @property
    def metadata(self) -> Dict[str, Any]:
        """Format, geometry, header entries, sensor, serial, time shift (µs) and notes."""
        return self._native.metadata

    @property
    def geometry(self) -> Optional[Tuple[int, int]]:
        """The sensor size ``(width, height)`` when the file states it, else ``None``."""
        return self._native.geometry

    @property
    def time_range(self) -> Optional[Tuple[int, int]]:
        """``(first, last)`` event time stamps, µs of camera time (the first call reads the
        whole file); ``None`` without events."""
        return self._native.time_range

    @property
    def triggers(self) -> Dict[str, np.ndarray]:
        """External trigger edges: arrays ``t`` (µs), ``channel`` and ``value``."""
        return self._native.triggers

    @property
    def report(self) -> Dict[str, Any]:
        """What the reader dropped or found odd in the whole file, as ``ebiv info`` says."""
        return self._native.report

    def read(self, t0: Union[int, str, None] = None, t1: Union[int, str, None] = None) -> Events:
        """The events with ``t0 <= t < t1``, in µs of camera time as the file stores it (the
        scale of :attr:`time_range`; texts such as "1.5s" are µs too), ``None``: from the
        start, to the end. Unlike the ``time`` setting of :func:`process`, which counts from
        the first event, these are absolute. The arrays take over the decoder's buffers: no
        copy is made after decoding. With an index (:func:`index`) a RAW file is read from
        close to ``t0`` instead of from its start."""
        return Events(*self._native.read(t0, t1))

    def chunks(self, duration: Union[int, str, None] = None, count: Optional[int] = None) -> Iterator[Events]:
        """Iterate over the events in chunks of ``duration`` (µs or "10ms"; windows aligned to
        the first event, those without events skipped) or of ``count`` events; neither: the
        reader's batches (about 1 MB of the file each)."""
        native = self._native.chunks(duration, count)  # checks the arguments now
        return (Events(*chunk) for chunk in native)

    def __iter__(self) -> Iterator[Events]:
        return self.chunks()

    def __repr__(self) -> str:
        return repr(self._native).replace("ebiv.Recording", "Recording")


def open(path: PathLike, **reader_options: Any) -> Recording:  # noqa: A001 (as io.open)
    """Open an event recording (RAW EVT 2.0/2.1/3.0, DAT, AEDAT 2/3.1/4, Event Stream,
    CSV/text, NumPy, EBIV .evt). Reader options, as the command line's: ``geometry=(w, h)``,
    ``format="evt3"``, ``raw_encoding``, ``metavision_time``, ``columns``, ``time_unit``,
    ``delimiter``, ``polarity_values``."""
    return Recording(_ebiv.open(path, **reader_options), reader_options)


def index(path: PathLike, *, force: bool = False, **reader_options: Any) -> Optional[str]:
    """Build and store the index of a RAW recording (EVT 2.0, 2.1, 3.0) when it is missing
    or stale, as ``ebiv index`` does, so that reading from a time seeks instead of decoding
    everything before it. Returns where the index is stored; ``None`` for formats without
    one."""
    stored = _ebiv.index(path, force, **reader_options)
    return None if stored is None else os.fspath(stored)


def _progress(progress: Progress, what: str) -> Tuple[Optional[Callable[[int, int], Any]], Callable[[], None]]:
    """The callback for ``progress`` (a callable ``(done, total)``; ``True``: a tqdm bar if
    tqdm is installed, else a line on stderr) and what closes it."""
    if progress is None or progress is False:
        return None, lambda: None
    if callable(progress):
        return progress, lambda: None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        def line(done: int, total: int) -> None:
            print(f"\r{what}: {done}/{total}", end="", file=sys.stderr, flush=True)

        return line, lambda: print(file=sys.stderr)
    bar = tqdm(desc=what, total=0)

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    return update, bar.close


def _result(raw: Mapping[str, Any], decode_times: bool) -> Any:
    if _dataset.have_xarray():
        return _dataset.to_xarray(raw, decode_times)
    return _dataset.to_dict(raw)


def _source(source: Any, settings: Dict[str, Any]) -> Any:
    """Paths pass through; a :class:`Recording` gives its path and its reader options (under
    the keywords given); ``Events`` and sequences of arrays become ``(t, x, y, p)``."""
    if isinstance(source, (str, os.PathLike)) or hasattr(source, "keys"):
        return source
    if isinstance(source, Recording):
        for key, value in source.reader_options.items():
            settings.setdefault(key, value)
        return source.path
    try:
        return tuple(source)
    except TypeError:
        raise TypeError(
            "invalid parameter `source`: give a path, a Recording, or event arrays (t, x, y, p)"
        ) from None


def process(
    source: Union[PathLike, Events, Tuple[Any, Any, Any, Any], Dict[str, Any]],
    method: Optional[str] = None,
    *,
    progress: Progress = None,
    decode_times: bool = True,
    **settings: Any,
) -> Any:
    """Velocity fields of a recording, as ``ebiv process`` measures them.

    ``source``: a path (or a :class:`Recording`), or events as arrays ``(t, x, y, p)``
    (pass ``geometry=(w, h)`` when the largest coordinates are not the sensor's size).
    ``method``: ``corrsum`` (the default), ``motion``, ``piv`` (frames rebuilt from the
    events) or ``pulsed``; ``None`` leaves it to ``config``. ``settings``: any setting of ``ebiv process`` or of its configuration file,
    with ``_`` for ``-`` (``slab="5ms"``, ``window=[64, 32]``, ``time="::5ms"``,
    ``uncertainty=False``), ``config="ebiv.toml"`` to start from a file, reader options such as
    ``geometry``, and ``output="flow.nc"`` to write the file as well. :func:`settings` lists
    them.

    Returns an ``xarray.Dataset`` with the variables, attributes and units of the NetCDF
    output (``time`` decoded to dates unless ``decode_times=False``), or without xarray a
    dict of NumPy arrays with ``attrs`` and ``variable_attrs``. Warnings (empty fields, no
    valid vector) are Python warnings; errors are ``ValueError`` (a setting),
    ``OSError`` (a file) or :class:`EbivError` (the data).
    """
    callback, close = _progress(progress, "fields")
    try:
        source = _source(source, settings)
        raw = _ebiv.process(source, method, callback, **settings)
    finally:
        close()
    return _result(raw, decode_times)


def live(
    source: PathLike,
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
    on_field: Optional[Callable[[Any, Dict[str, Any]], Any]] = None,
    decode_times: bool = True,
    **settings: Any,
) -> Dict[str, Any]:
    """Velocity fields while the camera records, as ``ebiv live`` computes them.

    ``source``: a recording still being written (``follow=True``: wait for new data at its
    end, and end once it has not grown for ``idle``), ``"-"`` for standard input, or a
    finished recording (``replay=True`` plays it at ``speed`` times its own rate; otherwise
    it is read as fast as the fields are computed). ``method`` and ``settings`` are those of
    :func:`process`, and ``every="5ms"`` the time between fields (default: one per slab, or
    the STEP of ``time``); the fields, their times and their slabs are those :func:`process`
    gives on the finished recording. When the machine cannot keep up with a live input,
    whole fields are dropped (at most ``queue`` slabs wait).

    ``on_field(dataset, stats)`` is called with every field as it is ready: a dataset of one
    time, as :func:`process` returns, and a dict of the run's counts (``events``, ``fields``,
    ``dropped``, ``dropped_before``, ``event_rate``, ``field_rate``, ``latency_ms``,
    ``latency_p99_ms``, ``elapsed_s``). A false return value (not ``None``) stops the run. ``output=`` appends
    the fields to a .nc or .csv file as they come (.npz at the end); ``serve="127.0.0.1:8080"``
    serves the live view (another address needs ``allow_remote=True``). Ctrl-C stops the run.

    Returns the summary: the counts, the latency percentiles (``latency_p50_ms``,
    ``latency_p99_ms``, ``latency_max_ms``, from a slab's end to its field), ``stopped`` and
    the reader's ``warnings``.
    """
    callback = None
    if on_field is not None:
        def callback(raw: Mapping[str, Any], stats: Dict[str, Any]) -> Any:
            return on_field(_result(raw, decode_times), stats)
    return _ebiv.live(
        os.fspath(source), method, follow=follow, idle=idle, replay=replay, speed=speed,
        every=every, queue=queue, serve=serve, allow_remote=allow_remote, on_field=callback, **settings,
    )


def piv(*images: Any, progress: Progress = None, decode_times: bool = True, **settings: Any) -> Any:
    """Cross-correlation PIV of images (paths or 2-D arrays of one size), pairs (1,2),
    (3,4), … or with ``sequence=True`` (1,2), (2,3), …; ``ensemble=True`` for one field of
    all pairs; ``dt="2ms"`` for velocities in px/ms instead of displacements in px. Settings
    as ``ebiv process --method piv``. Returns a dataset as :func:`process` does."""
    callback, close = _progress(progress, "fields")
    try:
        raw = _ebiv.piv(*images, progress=callback, **settings)
    finally:
        close()
    return _result(raw, decode_times)


class Simulation(NamedTuple):
    """A simulated recording: its ``events``, sensor ``geometry`` ``(width, height)``, the
    true velocity field ``truth`` (a dataset as :func:`process` returns) and, when asked
    for, the particles' ``tracks`` (arrays ``id``, ``t_us``, ``x``, ``y``, ``z``, ``u``,
    ``v``)."""

    events: Events
    geometry: Tuple[int, int]
    truth: Any
    tracks: Optional[Dict[str, np.ndarray]]


def simulate(
    scenario: Union[str, PathLike],
    *,
    seed: Optional[int] = None,
    duration: Union[int, str, None] = None,
    tracks: bool = False,
    progress: Progress = None,
    decode_times: bool = True,
) -> Simulation:
    """Simulate a recording with its ground truth, as ``ebiv simulate`` does: ``scenario``
    is a ready example (:func:`examples`), a scenario file, or TOML text."""
    callback, close = _progress(progress, "simulating")
    try:
        raw = _ebiv.simulate(scenario, seed, duration, tracks, callback)
    finally:
        close()
    return Simulation(
        Events(*raw["events"]),
        tuple(raw["geometry"]),
        _result(raw["truth"], decode_times),
        raw.get("tracks"),
    )


def _field(field: Any) -> Any:
    if isinstance(field, (str, os.PathLike)):
        return field
    return _dataset.from_field(field)


def assess(
    field: Any,
    truth: Optional[PathLike] = None,
    *,
    truth_example: Optional[str] = None,
    outlier_px: Optional[float] = None,
    outlier_floor: Optional[float] = None,
    outlier_fixed: Optional[float] = None,
    mm_per_px: Optional[float] = None,
    frame_interval: Union[int, str, None] = None,
) -> Dict[str, Any]:
    """Errors of a field (a dataset from :func:`process`, or a field file) against the
    truth, as ``ebiv assess`` reports them: ``truth`` is a truth field or scenario file,
    ``truth_example`` a ready scenario. Returns the metrics as a dict (bias, random error,
    RMS, outliers, uncertainty coverage, …; see docs/assess.md)."""
    return _ebiv.assess(
        _field(field),
        truth,
        truth_example,
        outlier_px,
        outlier_floor,
        outlier_fixed,
        mm_per_px,
        frame_interval,
    )


def filter(  # noqa: A001 (as ebiv filter)
    source: Union[PathLike, Events, Tuple[Any, Any, Any, Any], Dict[str, Any]],
    output: Optional[PathLike] = None,
    **settings: Any,
) -> Dict[str, Any]:
    """Remove noise events, as ``ebiv filter`` does (docs/denoise.md).

    ``source``: a path (or a :class:`Recording`), or events as arrays ``(t, x, y, p)`` (pass
    ``geometry=(w, h)`` when the largest coordinates are not the sensor's size). Settings:
    ``denoise`` (``"hot-pixels,refractory,correlation"``, any of them, or ``"all"``;
    required), ``denoise_dt``, ``denoise_refractory``, ``denoise_hot_factor``,
    ``denoise_hot_learn``, and reader options. The same settings are keywords of
    :func:`process` and :func:`live`.

    With ``output``, the kept events are written in the format of its extension (.raw,
    .aedat4, .csv, .npy, .npz). Returns the counts: ``events_in``, ``events_out``,
    ``removed_hot_pixels``, ``removed_refractory``, ``removed_correlation`` (``None`` for a
    filter that did not run), ``hot_pixels``, ``filters``; and without ``output`` the kept
    events as :class:`Events` under ``events``."""
    source = _source(source, settings)
    result = dict(_ebiv.filter(source, output, **settings))
    if "events" in result:
        result["events"] = Events(*result["events"])
    return result


def write(field: Any, path: PathLike) -> None:
    """Write a field (a dataset from :func:`process`, or a field file to convert) as
    NetCDF (.nc), CSV, NPZ, Tecplot (.dat) or VTK (.vtk), as ``ebiv process -o`` does."""
    _ebiv.write(_field(field), path)


def stats(
    field: Any,
    *,
    period: Union[int, str, None] = None,
    phases: int = 8,
    phase_origin: Union[int, str, None] = None,
    include_replaced: bool = False,
    mm_per_px: Optional[float] = None,
    output: Optional[PathLike] = None,
    triggers: Optional[Union[PathLike, "Recording"]] = None,
    trigger_polarity: str = "rising",
    trigger_channel: Optional[int] = None,
    **reader_options: Any,
) -> Any:
    """Flow statistics of a field series (a dataset from :func:`process`, or a field file),
    as ``ebiv stats`` computes them: at every node ``u_mean``, ``v_mean``, ``u_rms``,
    ``v_rms``, the Reynolds stresses ``uu``, ``vv``, ``uv`` and ``count``, the valid vectors
    averaged. Invalid vectors are left out; replaced ones too unless ``include_replaced``.
    ``period`` (µs or ``"20ms"``) sorts the fields into ``phases`` bins of the period, from
    ``phase_origin`` (default: the first field's time), adding the dimension ``phase``.
    ``triggers`` (the recording the fields were measured from: a path, with reader options
    as keywords, or a :class:`Recording`) sorts them by their fraction of the interval
    between the trigger edges (``trigger_polarity``: rising, falling or any; on
    ``trigger_channel``) around them; fields outside the triggers are left out
    (``fields_outside_triggers``). ``output=`` also writes the file (.nc or .csv). Returns an
    ``xarray.Dataset`` identical to ``xarray.open_dataset`` of the command's .nc file (a dict
    without xarray)."""
    if isinstance(triggers, Recording):
        for key, value in triggers.reader_options.items():
            reader_options.setdefault(key, value)
        triggers = triggers.path
    raw = _ebiv.stats(_field(field), period, phases, phase_origin, include_replaced, mm_per_px,
                      None if output is None else os.fspath(output),
                      None if triggers is None else os.fspath(triggers), trigger_polarity,
                      trigger_channel, reader_options or None)
    return _result(raw, False)


def derive(
    field: Any,
    quantities: Union[str, Sequence[str]] = "all",
    *,
    mm_per_px: Optional[float] = None,
    output: Optional[PathLike] = None,
    decode_times: bool = True,
) -> Any:
    """Quantities derived from the velocity gradient of a field series (a dataset from
    :func:`process`, or a field file), as ``ebiv derive`` computes them: ``vorticity``
    (dv/dx - du/dy), ``divergence``, the strain rates ``e_xx``, ``e_yy``, ``e_xy`` and
    ``swirling_strength``; ``quantities`` names them (a list, or comma-separated text;
    ``"strain"``, ``"all"``). Central differences, one-sided at the grid's edges and next to
    invalid vectors, NaN where neither neighbour has a value (docs/derived.md); 1/ms, or 1/s
    with a calibration (``mm_per_px`` for files without one). ``output=`` also writes the
    file (.nc, .csv or .npz). Returns the field as :func:`process` does, with the quantities
    as variables."""
    if not isinstance(quantities, str):
        quantities = ",".join(quantities)
    raw = _ebiv.derive(_field(field), quantities, mm_per_px,
                       None if output is None else os.fspath(output))
    return _result(raw, decode_times)


def examples() -> Dict[str, str]:
    """The ready scenarios of :func:`simulate`: name and description."""
    return dict(_ebiv.examples())


Tracks = Union[PathLike, Any]


def track(
    source: Union[PathLike, Events, Tuple[Any, Any, Any, Any], Dict[str, Any]],
    *,
    time: Union[str, Tuple[Union[int, str, None], Union[int, str, None]], None] = None,
    absolute_time: bool = False,
    output: Optional[PathLike] = None,
    progress: Progress = None,
    **settings: Any,
) -> Any:
    """Particle tracks of a recording, as ``ebiv track`` follows them: position, velocity
    and acceleration at every sample, each with its standard uncertainty, the path's
    curvature and the fit's quality.

    ``source``: a path (or a :class:`Recording`, with its reader options), or events as
    arrays ``(t, x, y, p)`` (with ``geometry=(w, h)`` when the largest coordinates are not
    the sensor's size). ``time``: the interval tracked, ``"START:END"`` text (``"10ms:60ms"``;
    either end may be left out) or a pair ``(start, end)`` of durations (µs or texts with
    units, ``None`` for an open end), from the first event or, with ``absolute_time=True``,
    in µs of camera time. ``settings``: the tracking settings of ``ebiv track`` with ``_``
    for ``-`` (``slab="500us"``, ``min_events=4``, ``gate=3.0``, ``max_speed``, ``max_gap``,
    ``min_duration``, ``fit_window``, ``degree``, ``sample``, ``latency``, ``polarity``;
    :func:`track_settings` lists them with their defaults) and reader options.
    ``output="tracks.csv"`` (or ``.npz``, ``.nc``) also writes the file, byte for byte the
    command's.

    Returns an ``xarray.Dataset`` identical to ``xarray.open_dataset`` of the command's
    ``.nc`` file: one row per sample along ``sample``, the variables ``track_id``, ``t_us``
    (µs of camera time), ``x``, ``y``, ``u``, ``v``, ``ax``, ``ay``, their uncertainties
    ``x_unc`` … ``ay_unc``, ``curvature``, ``events`` and ``residual`` with units, and the
    settings as attributes; without xarray a dict of arrays with ``attrs`` and
    ``variable_attrs``. ``progress`` counts bytes of the file read. Errors are
    ``ValueError`` (a setting, ``time``), ``OSError`` (a file) or :class:`EbivError` (the
    data).
    """
    callback, close = _progress(progress, "tracking")
    try:
        source = _source(source, settings)
        raw = _ebiv.track(source, time, absolute_time, output, callback, **settings)
    finally:
        close()
    return _result(raw, True)


def _track_columns(tracks: Tracks) -> Tuple[Any, Dict[str, Any]]:
    """The samples of ``tracks`` as the extension takes them (a CSV file's path as it is,
    else a dict of column arrays) and the tracks' global attributes."""
    if isinstance(tracks, (str, os.PathLike)):
        path = os.fspath(tracks)
        suffix = os.path.splitext(path)[1].lower()
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as npz:
                columns = {name: npz[name] for name in npz.files if name != "attributes"}
                lines = [str(line) for line in npz["attributes"]] if "attributes" in npz.files else []
            return columns, dict(line.split("=", 1) for line in lines if "=" in line)
        if suffix != ".nc":
            return path, {}
        if not _dataset.have_xarray():
            raise ImportError(f"reading the tracks of {path} needs xarray; or give the .csv or .npz file")
        import xarray as xr

        with xr.open_dataset(path) as ds:
            tracks = ds.load()
    if hasattr(tracks, "data_vars"):
        return {name: np.asarray(tracks[name].values) for name in tracks.variables}, dict(tracks.attrs)
    if hasattr(tracks, "keys"):
        columns = {k: tracks[k] for k in tracks.keys() if k not in ("attrs", "variable_attrs")}
        attrs = tracks["attrs"] if "attrs" in tracks.keys() else {}
        return columns, dict(attrs)
    raise TypeError(
        "invalid parameter `tracks`: give tracks as a dataset or dict from ebiv.track, or a track file"
    )


def _track_geometry(geometry: Union[None, str, Tuple[int, int]], attrs: Mapping[str, Any]) -> Tuple[int, int]:
    """The sensor size: ``geometry`` (``(w, h)`` or ``"WxH"``), else the tracks' attributes
    ``sensor_width`` and ``sensor_height`` when they state it."""
    if geometry is None:
        try:
            return int(attrs["sensor_width"]), int(attrs["sensor_height"])
        except (KeyError, TypeError, ValueError):
            raise ValueError(
                "invalid parameter `geometry`: give the sensor size (width, height) of the recording "
                "the tracks come from (as ebiv.open(path).geometry or ebiv.simulate(...).geometry "
                "give it); the tracks do not state it"
            ) from None
    try:
        if isinstance(geometry, str):
            width, height = geometry.lower().split("x")
            return int(width), int(height)
        width, height = geometry
        return int(width), int(height)
    except (TypeError, ValueError):
        raise ValueError(
            f"invalid parameter `geometry`: {geometry!r}: give (width, height) or \"WxH\""
        ) from None


def bin_tracks(
    tracks: Tracks,
    bin: float = 16,  # noqa: A002 (the flag --bin)
    *,
    interval: Union[int, str, None] = None,
    min_tracks: int = 3,
    geometry: Union[None, str, Tuple[int, int]] = None,
    decode_times: bool = True,
) -> Any:
    """The mean velocity field of tracks, as ``ebiv track --bin`` writes it to ``--field``:
    the velocities of the samples averaged in square bins of ``bin`` px, one field per
    ``interval`` (µs or "100ms"; ``None``: one over all tracks), a bin crossed by fewer than
    ``min_tracks`` tracks left invalid.

    ``tracks``: a dataset or dict from :func:`track`, a dict of the columns (``track_id``,
    ``t_us``, ``x``, ``y``, ``u``, ``v`` at least), or a track file (.csv, .npz; .nc with
    xarray). ``geometry``: the sensor size ``(width, height)`` the grid covers; by default
    the tracks' ``sensor_width`` and ``sensor_height`` attributes (datasets of :func:`track`,
    .nc and .npz files); a dict of columns or a CSV file needs it given
    (``ebiv.open(path).geometry``). The tracks' attributes (settings and source, not their
    ``method``) are added to the field's, as the command adds them.

    Returns the dataset :func:`process` returns (``u``, ``v``, ``u_unc``, ``v_unc``,
    ``status``, …; ``event_count`` holds the samples of a bin, ``slab_us`` the interval),
    identical to ``xarray.open_dataset`` of the command's field file.
    """
    columns, attrs = _track_columns(tracks)
    size = _track_geometry(geometry, attrs)
    own = [(k, v) for k, v in attrs.items() if isinstance(v, str) and k != "software"]
    raw = _ebiv.bin_tracks(columns, size, float(bin), interval, min_tracks, own)
    return _result(raw, decode_times)


def assess_tracks(
    tracks: Tracks,
    truth_tracks: Union[PathLike, Mapping[str, Any], "Simulation"],
    *,
    scenario: Union[str, PathLike, None] = None,
    truth_example: Optional[str] = None,
) -> Dict[str, Any]:
    """Tracks scored against the simulator's particle paths, as ``ebiv assess TRACKS
    --truth-tracks TRUTH`` scores them (its ``tracks.json``).

    ``tracks``: as :func:`bin_tracks` takes them. ``truth_tracks``: the paths
    ``ebiv simulate --tracks`` writes (a CSV file), or those of
    ``ebiv.simulate(..., tracks=True)`` (the :class:`Simulation` or its ``tracks``).
    ``scenario`` (a ready example's name, a scenario file or its TOML text) or
    ``truth_example`` (a ready example) gives the image, light sheet and walls that decide
    which particles are in view; neither: the paths' extent and the default light sheet.

    Returns a dict: ``particles`` (in view long enough to count), ``particles_tracked``,
    ``yield_fraction``, ``tracks``, ``spurious``, ``spurious_fraction``, ``mean_length_ms``,
    ``samples``, ``position_rms``, ``position_bias_along``, ``velocity_rms``,
    ``acceleration_rms``, ``peak_speed``, ``peak_acceleration``,
    ``velocity_coverage_2sigma``, ``position_coverage_2sigma`` and ``lag_us``.
    """
    columns, _ = _track_columns(tracks)
    if isinstance(truth_tracks, Simulation):
        if truth_tracks.tracks is None:
            raise ValueError(
                "invalid parameter `truth_tracks`: the simulation has no tracks; simulate with tracks=True"
            )
        truth_tracks = truth_tracks.tracks
    if not isinstance(truth_tracks, (str, os.PathLike)) and hasattr(truth_tracks, "keys"):
        truth_tracks = {k: truth_tracks[k] for k in truth_tracks.keys()}
    return _ebiv.assess_tracks(columns, truth_tracks, scenario, truth_example)


def track_settings() -> Dict[str, Dict[str, Any]]:
    """Every tracking setting :func:`track` takes as a keyword: the kind of value, default
    and summary, from the one list the flags of ``ebiv track`` are made of."""
    return {
        key: {"value": value, "default": default, "summary": summary}
        for key, value, default, summary in _ebiv.track_setting_names()
    }


#: Settings of ``ebiv process`` that Python takes elsewhere: the recording is ``source``,
#: images are the arguments of :func:`piv`, and figures are drawn with matplotlib.
_NOT_KEYWORDS = {"input", "images", "png", "arrow_stride"}


def settings() -> Dict[str, Dict[str, Any]]:
    """Every setting :func:`process` and :func:`piv` take as keywords: group, default and
    summary, from the one schema the command line and the configuration file use."""
    return {
        key: {"group": group, "default": default, "summary": summary}
        for key, group, default, summary in _ebiv.setting_names()
        if key not in _NOT_KEYWORDS
    }
