"""ebiv.dask: many recordings, or long ones, measured in time shards on a Dask cluster.

A run's fields are independent: each is measured from the events of its own time slab
(plus τ, or the frames' span). :func:`shards` splits the fields of a recording into
consecutive groups of about ``shard`` seconds; each shard is one task that opens the file
itself and measures its fields with ``ebiv.process(..., time=…)``, reading the events its
first field needs onwards, so shards overlap by what the method needs and no field is
measured twice. Only paths, time ranges and settings travel to the workers; results come
back as datasets and are joined in time order, or each shard writes its own file and an
index lists them.

The sharded result equals ``ebiv.process`` of the whole recording exactly. Any Dask
deployment runs it unchanged::

    from dask.distributed import Client
    client = Client("tcp://scheduler:8786")          # or LocalCluster(), or dask-jobqueue
    ds = ebiv.dask.process(["run1.raw", "run2.raw"], client=client, slab="5ms")

Needs ``dask[distributed]`` (``pip install "./crates/ebiv-py[dask]"``).
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Union

import numpy as np

from . import _dataset, _ebiv
PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["Shard", "shards", "process"]


class Shard(NamedTuple):
    """One task: the fields of ``recording`` at ``time`` (``START:END:STEP`` in µs from
    the time origin, as the ``time`` setting takes it), ``fields`` of them, the ``index``-th
    shard of its recording; ``first_us``/``last_us`` are its fields' camera times."""

    recording: str
    index: int
    time: str
    fields: int
    first_us: int
    last_us: int


def shards(
    recording: PathLike,
    method: Optional[str] = None,
    *,
    shard: Union[int, str] = "1s",
    **settings: Any,
) -> List[Shard]:
    """The shards of a run over ``recording``: its planned fields (those ``settings``, and
    ``time`` if given, select) in groups spanning about ``shard`` (µs or "2s") each."""
    span = _ebiv.duration_us("shard", shard)
    if span <= 0:
        raise ValueError("invalid parameter `shard`: must be positive")
    recording = os.path.abspath(os.fspath(recording))
    plan = _ebiv.plan(recording, method, **settings)
    times = np.asarray(plan["times"], dtype=np.int64)
    origin = int(plan["time_origin_us"])
    step = int(times[1] - times[0]) if len(times) > 1 else 1
    out: List[Shard] = []
    start = 0
    while start < len(times):
        end = int(np.searchsorted(times, times[start] + span, side="left"))
        end = max(end, start + 1)
        first, last = int(times[start]), int(times[end - 1])
        spec = f"{first - origin}us:{last - origin}us:{step}us"
        out.append(Shard(recording, len(out), spec, end - start, first, last))
        start = end
    return out


def _measure(shard: Shard, method: Optional[str], settings: Dict[str, Any], output: Optional[str]) -> Any:
    """Run one shard on a worker: its dataset (times undecoded), or the path written. A shard
    whose fields hold no event at all gives gaps, as those fields do in a whole run."""
    from . import _result, _source

    settings = dict(settings, time=shard.time)
    if output is not None:
        settings["output"] = output
    raw = _ebiv.process(_source(shard.recording, settings), method, None, True, **settings)
    return output if output is not None else _result(raw, False)


#: Settings that name files.
_PATH_SETTINGS = ("config", "mask")


def _reader_options(settings: Dict[str, Any]) -> Dict[str, Any]:
    """The reader options among ``settings`` (``geometry``, ``format``, …)."""
    return {k: v for k, v in settings.items() if k in _ebiv.READER_OPTIONS and v is not None}


def _client(client: Any) -> Any:
    if client is not None:
        return client
    from dask.distributed import get_client

    return get_client()


def process(
    recordings: Union[PathLike, Sequence[PathLike]],
    method: Optional[str] = None,
    *,
    client: Any = None,
    shard: Union[int, str] = "1s",
    output_dir: Optional[PathLike] = None,
    decode_times: bool = True,
    **settings: Any,
) -> Any:
    """Measure ``recordings`` (one path or several) on the Dask cluster of ``client`` (by
    default the current one, ``dask.distributed.get_client()``), in shards of about
    ``shard`` of recording time. ``method`` and ``settings`` are those of
    :func:`ebiv.process`.

    Returns, for one recording, its dataset (all shards in time order, equal to
    ``ebiv.process`` of the whole), for several a dict of datasets by path. With
    ``output_dir``, each shard is written there as ``NAME_shardNNNN.nc`` instead, beside an
    index ``NAME_shards.json`` (files, time ranges and field counts in time order), and the
    index paths are returned.
    """
    if settings.get("output") is not None:
        raise ValueError("invalid parameter `output`: give output_dir; each shard writes its own file")
    if (method or "") == "pulsed":
        raise ValueError(
            "invalid parameter `method`: pulsed runs find their pulse timing from the start of "
            "their time span, which differs between shards; measure them with ebiv.process"
        )
    for key in _PATH_SETTINGS:  # workers resolve paths in their own working folders
        if settings.get(key) is not None:
            settings[key] = os.path.abspath(os.fspath(settings[key]))
    client = _client(client)
    single = isinstance(recordings, (str, os.PathLike))
    # Absolute paths: workers resolve them in their own working folders.
    paths = [os.path.abspath(os.fspath(r)) for r in ([recordings] if single else recordings)]
    if output_dir is not None:
        output_dir = os.path.abspath(os.fspath(output_dir))
    settings = {k: v for k, v in settings.items() if k != "time" or v is not None}
    for path in paths:
        # Built once here, used by every worker that opens the file (beside it, or in the
        # index cache of a shared home); a no-op where it exists or the format needs none.
        # Without it the shards are the same, only slower to reach their start.
        try:
            _ebiv.index(path, False, **_reader_options(settings))
        except OSError as e:
            warnings.warn(f"{path}: no index ({e}); shards decode the file from its start")
    plans = {p: shards(p, method, shard=shard, **settings) for p in paths}
    settings.pop("time", None)
    futures = {}
    for path, parts in plans.items():
        outputs = [None] * len(parts)
        if output_dir is not None:
            os.makedirs(output_dir, exist_ok=True)
            stem = os.path.splitext(os.path.basename(path))[0]
            outputs = [os.path.join(os.fspath(output_dir), f"{stem}_shard{s.index:04d}.nc") for s in parts]
        futures[path] = [
            client.submit(_measure, s, method, settings, out, pure=False)
            for s, out in zip(parts, outputs)
        ]
    results: Dict[str, Any] = {}
    for path, parts in plans.items():
        gathered = client.gather(futures[path])
        if output_dir is not None:
            results[path] = _write_index(path, parts, gathered, os.fspath(output_dir))
        else:
            results[path] = _join(gathered, decode_times)
    if single:
        return results[paths[0]]
    given = [os.fspath(r) for r in recordings]
    return {name: results[path] for name, path in zip(given, paths)}


def _join(datasets: List[Any], decode_times: bool) -> Any:
    """The shards' datasets (times undecoded) as one, in time order."""
    if not datasets:
        raise ValueError("no shard to join")
    if not _dataset.have_xarray():
        raise ImportError("joining shards needs xarray; pass output_dir to write files instead")
    import xarray as xr

    joined = xr.concat(datasets, dim="time", data_vars="minimal", coords="minimal",
                       compat="identical", combine_attrs="identical", join="exact")
    return xr.decode_cf(joined, decode_times=decode_times)


def _write_index(path: str, parts: List[Shard], files: List[str], output_dir: str) -> str:
    stem = os.path.splitext(os.path.basename(path))[0]
    index = os.path.join(output_dir, f"{stem}_shards.json")
    entries = [
        {"file": os.path.basename(f), "fields": s.fields, "first_us": s.first_us, "last_us": s.last_us}
        for s, f in zip(parts, files)
    ]
    with open(index, "w") as out:
        json.dump({"recording": path, "shards": entries}, out, indent=1)
    return index
