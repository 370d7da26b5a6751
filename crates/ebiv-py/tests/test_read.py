"""ebiv.open: metadata, exact events (checked against the shared data's expected values),
reading between times, and chunks."""

import hashlib
import json

import numpy as np
import pytest

import ebiv


def canonical_sha256(ev):
    """sha256 of records (x u16, y u16, p u8, t i64) sorted by (t, x, y, p): the shared
    data's definition."""
    order = np.lexsort((ev.p, ev.y, ev.x, ev.t))
    records = np.zeros(len(ev.t), dtype=[("x", "<u2"), ("y", "<u2"), ("p", "u1"), ("t", "<i8")])
    records["x"], records["y"] = ev.x[order], ev.y[order]
    records["p"], records["t"] = ev.p[order], ev.t[order]
    return hashlib.sha256(records.tobytes()).hexdigest()


@pytest.mark.parametrize("name", ["prophesee/evt3_test_pedestrians.raw", "prophesee/evt2_sample.raw",
                                  "prophesee/sample_ncars.dat", "inivation/sample.aedat4", "es/dvs.es"])
def test_every_event_is_read_exactly(data, name):
    path = data(name)
    expected = json.loads((path.parents[1] / "EXPECTED.json").read_text())[name]
    rec = ebiv.open(path)
    ev = rec.read()
    assert len(ev.t) == expected["n_events"]
    assert ev.t.dtype == np.int64 and ev.x.dtype == np.uint16 and ev.p.dtype == np.uint8
    assert int(ev.p.sum()) == expected["n_on"]
    assert rec.time_range == (expected["t_min"], expected["t_max"])
    assert canonical_sha256(ev) == expected["canonical_sha256"]
    first = [list(map(int, e)) for e in zip(ev.t[:3], ev.x[:3], ev.y[:3], ev.p[:3])]
    assert first == expected["first_events_file_order_t_x_y_p"][:3]


def test_arrays_own_their_memory_without_a_copy(data):
    ev = ebiv.open(data("prophesee/evt3_test_pedestrians.raw")).read()
    # The decoder's buffer is handed over: NumPy does not own it, and nothing copied it.
    assert not ev.t.flags.owndata and ev.t.base is not None
    assert ev.t.flags.c_contiguous


def test_metadata_and_geometry(data):
    rec = ebiv.open(data("prophesee/evt3_test_pedestrians.raw"))
    assert rec.geometry == (1280, 720)
    assert rec.metadata["format"].startswith("Prophesee RAW")
    assert rec.report["events"] == 5000
    assert "Recording" in repr(rec)


def test_reading_between_times_and_in_chunks(data):
    rec = ebiv.open(data("prophesee/evt2_sample.raw"))
    everything = rec.read()
    t0, t1 = rec.time_range
    a, b = t0 + (t1 - t0) // 3, t0 + 2 * (t1 - t0) // 3
    part = rec.read(a, b)
    keep = (everything.t >= a) & (everything.t < b)
    for column, whole in zip(part, everything):
        np.testing.assert_array_equal(column, whole[keep])
    by_count = list(rec.chunks(count=10_000))
    assert all(len(c.t) == 10_000 for c in by_count[:-1])
    np.testing.assert_array_equal(np.concatenate([c.t for c in by_count]), everything.t)
    by_time = list(rec.chunks(duration="10ms"))
    windows = [(c.t.min() - t0) // 10_000 for c in by_time]
    assert all(len(c.t) for c in by_time) and windows == sorted(set(windows))
    for k, c in zip(windows, by_time):
        assert (c.t.max() - t0) // 10_000 == k  # within one aligned window
    assert sum(len(c.t) for c in by_time) == len(everything.t)
    assert sum(len(c.t) for c in rec) == len(everything.t)


def test_whole_file_read_joins_the_batches_exactly(data):
    rec = ebiv.open(data("prophesee/evt2_sample.raw"))
    batches = list(rec)
    assert len(batches) > 1  # the whole-file read joins several batches
    everything = rec.read()
    for i, column in enumerate(everything):
        np.testing.assert_array_equal(np.concatenate([b[i] for b in batches]), column)


def test_bad_input_gives_the_command_line_messages(tmp_path, cli, data):
    with pytest.raises(FileNotFoundError, match="missing.raw"):
        ebiv.open(tmp_path / "missing.raw")
    junk = tmp_path / "junk.raw"
    junk.write_bytes(b"\x00\x01garbage" * 10)
    with pytest.raises(ebiv.EbivError) as err:
        ebiv.open(junk).read()
    message = cli("info", junk, check=False).stderr
    assert str(err.value) in message
    with pytest.raises(ValueError, match="geometry"):
        ebiv.open(data("prophesee/evt2_sample.raw"), geometry="12")
    with pytest.raises(ValueError, match="not a reader option"):
        ebiv.open(data("prophesee/evt2_sample.raw"), window=3)
    with pytest.raises(ValueError, match="duration"):
        list(ebiv.open(data("prophesee/evt2_sample.raw")).chunks(duration="-1ms"))


def test_chunks_by_time_skip_gaps(tmp_path):
    csv = tmp_path / "gap.csv"
    csv.write_text("t,x,y,p\n0,1,1,1\n5,2,2,0\n1000000,3,3,1\n1000003,4,4,1\n")
    chunks = list(ebiv.open(csv).chunks(duration="1ms"))
    assert [list(c.t) for c in chunks] == [[0, 5], [1_000_000, 1_000_003]]


def test_event_arrays_must_be_integers(simulated):
    t = np.arange(10, dtype=np.int64)
    xy = np.zeros(10, dtype=np.uint16)
    p = np.ones(10, dtype=np.uint8)
    with pytest.raises(ValueError, match="integers"):
        ebiv.process((t / 1e6, xy, xy, p))
    with pytest.raises(ValueError, match="integers"):
        ebiv.process((t, xy.astype(float), xy, p))
    with pytest.raises(ValueError, match="range"):
        ebiv.process((t.astype(np.uint64) + np.uint64(2**63), xy, xy, p))
    with pytest.raises(ValueError, match="range"):
        ebiv.process((t, xy, xy, p * 2))
