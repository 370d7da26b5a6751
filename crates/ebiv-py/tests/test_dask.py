"""ebiv.dask on a local cluster of two worker processes (loopback, no dashboard): the
sharded result equals the single-process one exactly."""

import json
import os

import numpy as np
import pytest
import xarray as xr

import ebiv
import ebiv.dask

distributed = pytest.importorskip("dask.distributed")

SETTINGS = {"window": [48, 32], "slab": "5ms", "time": "::2ms"}


@pytest.fixture(scope="module")
def recording(simulated, tmp_path_factory):
    """A copy of the shared recording: the index ebiv.dask writes beside it stays here."""
    import shutil

    path = tmp_path_factory.mktemp("dask") / "rec.raw"
    shutil.copy(simulated / "rec.raw", path)
    return path


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None)
    with distributed.Client(cluster) as client:
        yield client
    cluster.close()


def test_shards_cover_every_field_once(recording):
    whole = ebiv.process(recording, **SETTINGS)
    parts = ebiv.dask.shards(recording, shard="7ms", **SETTINGS)
    assert len(parts) > 2
    assert sum(s.fields for s in parts) == whole.sizes["time"]
    assert all(a.last_us < b.first_us for a, b in zip(parts, parts[1:]))


def test_sharded_equals_single_process(recording, client):
    rec = recording
    whole = ebiv.process(rec, **SETTINGS)
    sharded = ebiv.dask.process(rec, client=client, shard="7ms", **SETTINGS)
    xr.testing.assert_identical(sharded, whole)
    both = ebiv.dask.process([rec, rec], client=client, shard="10ms", method="motion", **SETTINGS)
    xr.testing.assert_identical(both[str(rec)], ebiv.process(rec, method="motion", **SETTINGS))


def test_shards_written_to_files_with_an_index(recording, client, tmp_path):
    rec = recording
    index = ebiv.dask.process(rec, client=client, shard="7ms", output_dir=tmp_path, **SETTINGS)
    entries = json.loads(open(index).read())["shards"]
    files = [xr.open_dataset(tmp_path / e["file"]).load() for e in entries]
    joined = xr.concat(files, dim="time", combine_attrs="identical")
    xr.testing.assert_identical(joined, ebiv.process(rec, **SETTINGS))


def test_bad_shard_lengths_and_settings_are_refused(recording, client):
    with pytest.raises(ValueError, match="shard"):
        ebiv.dask.shards(recording, shard="0ms")
    with pytest.raises(ValueError, match="shard"):
        ebiv.dask.shards(recording, shard="soon")
    with pytest.raises(ValueError, match="output_dir"):
        ebiv.dask.process(recording, client=client, output="x.nc")
    with pytest.raises(ValueError, match="pulsed"):
        ebiv.dask.process(recording, "pulsed", client=client)


def test_a_shard_without_events_is_gaps_not_an_error(recording):
    beyond = {"window": [48, 32], "slab": "5ms", "time": "100ms:110ms:5ms"}
    with pytest.raises(ebiv.EbivError, match="no event"):
        ebiv.process(recording, **beyond)
    with pytest.warns(UserWarning, match="no event"):
        raw = ebiv._ebiv.process(str(recording), None, None, True, **beyond)
    u = next(a for name, _, a, _ in raw["variables"] if name == "u")
    assert u.shape[0] == 3 and np.isnan(u).all()


def test_the_index_is_built_once_and_used(simulated, tmp_path):
    import shutil

    rec = tmp_path / "rec.raw"
    shutil.copy(simulated / "rec.raw", rec)
    plain = ebiv.open(rec).read(20_000, 30_000)
    stored = ebiv.index(rec)
    assert stored == str(rec) + ".ebividx"
    modified = os.path.getmtime(stored)
    assert ebiv.index(rec) == stored and os.path.getmtime(stored) == modified
    indexed = ebiv.open(rec).read(20_000, 30_000)
    for a, b in zip(indexed, plain):
        np.testing.assert_array_equal(a, b)
    csv = tmp_path / "e.csv"
    csv.write_text("t,x,y,p\n1,2,3,1\n")
    assert ebiv.index(csv) is None
