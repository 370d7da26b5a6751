"""HDF5 event files: Metavision's (ECF-compressed or plain) and DSEC-style columns, read with
the same names and results as the command line."""

import json

import numpy as np
import pytest

import ebiv
from conftest import REPO
from test_read import canonical_sha256

FIXTURES = REPO / "crates" / "ebiv" / "tests" / "data" / "hdf5"


def expected(name):
    stored = np.load(FIXTURES / name)
    return {k: stored[k] for k in ("t", "x", "y", "p")}


@pytest.mark.parametrize("name,truth", [
    ("metavision_ecf.hdf5", "metavision.expected.npz"),
    ("metavision_plain.hdf5", "metavision.expected.npz"),
    ("dsec_columns.h5", "dsec.expected.npz"),
])
def test_every_layout_reads_its_events(name, truth):
    rec = ebiv.open(FIXTURES / name)
    ev = rec.read()
    want = expected(truth)
    for k in ("t", "x", "y"):
        np.testing.assert_array_equal(getattr(ev, k), want[k])
    np.testing.assert_array_equal(ev.p, (want["p"] > 0).astype(np.uint8))
    assert rec.metadata["format"] == "HDF5"


def test_triggers_geometry_and_time_shift():
    rec = ebiv.open(FIXTURES / "metavision_ecf.hdf5")
    want = expected("metavision.expected.npz")
    tr = rec.triggers
    np.testing.assert_array_equal(tr["t"], want["t"][[100, 900, 2000, 4000]] + 1)
    np.testing.assert_array_equal(tr["channel"], [0, 0, 3, 3])
    np.testing.assert_array_equal(tr["value"], [1, 0, 1, 0])
    assert rec.geometry == (640, 480)
    shifted = ebiv.open(FIXTURES / "metavision_ecf.hdf5", metavision_time=True).read()
    assert shifted.t[0] == 0


def test_reading_between_times_uses_the_index():
    want = expected("metavision.expected.npz")
    t0 = int(want["t"][0])
    ev = ebiv.open(FIXTURES / "metavision_ecf.hdf5").read(t0 + 20_000, t0 + 60_000)
    keep = (want["t"] >= t0 + 20_000) & (want["t"] < t0 + 60_000)
    np.testing.assert_array_equal(ev.t, want["t"][keep])


def test_the_command_line_reads_the_same(cli, tmp_path):
    out = tmp_path / "events.npz"
    cli("convert", FIXTURES / "dsec_columns.h5", out, "--geometry", "640x480")
    converted = np.load(out)
    np.testing.assert_array_equal(converted["t"], expected("dsec.expected.npz")["t"])


def test_a_damaged_file_raises_a_clear_error(tmp_path):
    bytes_ = bytearray((FIXTURES / "metavision_ecf.hdf5").read_bytes())
    damaged = tmp_path / "damaged.hdf5"
    damaged.write_bytes(bytes_[: len(bytes_) // 2])
    with pytest.raises(Exception) as err:
        ebiv.open(damaged).read()
    assert "damaged.hdf5" in str(err.value)


@pytest.mark.parametrize("name", ["hdf5/ecf_small.hdf5", "hdf5/generic_dsec.h5"])
def test_shared_samples_read_exactly(data, name):
    path = data(name)
    want = json.loads((path.parents[1] / "EXPECTED.json").read_text())[name]
    ev = ebiv.open(path).read()
    assert len(ev.t) == want["n_events"]
    assert canonical_sha256(ev) == want["canonical_sha256"]
