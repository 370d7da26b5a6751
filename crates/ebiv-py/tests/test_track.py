"""ebiv.track, ebiv.bin_tracks and ebiv.assess_tracks give what `ebiv track` and `ebiv assess
--truth-tracks` give: the same tracks, files, binned field and scores, for the same settings."""

import _thread
import json

import numpy as np
import pytest
import xarray as xr

import ebiv

#: Settings away from the defaults, to see that each keyword reaches the library.
SETTINGS = {"sample": "1ms", "max_gap": 2000, "min_events": 3}
FLAGS = ["--sample", "1ms", "--max-gap", "2000", "--min-events", "3"]


@pytest.fixture(scope="module")
def vortex(tmp_path_factory, cli):
    """20 ms of the `vortex` example with its particle paths, tracked by the command: the
    tracks as NetCDF with the binned field, as CSV, and their scores."""
    d = tmp_path_factory.mktemp("vortex")
    cli("simulate", "--example", "vortex", "--duration", "20ms", "--seed", "5",
        "-o", d / "rec.raw", "--tracks", d / "truth.csv")
    cli("track", d / "rec.raw", *FLAGS, "-o", d / "cli.nc",
        "--bin", "16", "--bin-interval", "10ms", "--field", d / "field.nc")
    cli("track", d / "rec.raw", *FLAGS, "-o", d / "cli.csv")
    cli("assess", d / "cli.csv", "--truth-tracks", d / "truth.csv", "--truth-example", "vortex",
        "-o", d / "report")
    return d


@pytest.fixture(scope="module")
def tracks(vortex, tmp_path_factory):
    """The tracks of `ebiv.track` (also written to py.csv)."""
    return ebiv.track(str(vortex / "rec.raw"), output=vortex / "py.csv", **SETTINGS)


def test_tracks_equal_the_command_line(vortex, tracks):
    xr.testing.assert_identical(tracks, xr.open_dataset(vortex / "cli.nc").load())
    assert tracks.attrs["method"] == "particle tracking"
    assert tracks.attrs["sample"] == "1ms" and tracks.attrs["min-events"] == "3"
    assert tracks.u.attrs["units"] == "px/ms"
    assert np.unique(tracks.track_id).size > 500


def test_the_output_file_is_the_command_line_s(vortex, tracks):
    assert (vortex / "py.csv").read_bytes() == (vortex / "cli.csv").read_bytes()
    assert not list(vortex.glob("*.partial"))


def test_an_interval_a_recording_and_event_arrays(vortex, cli, tmp_path):
    rec = ebiv.open(vortex / "rec.raw")
    cli("track", rec.path, "--time", "5ms:12ms", "--slab", "400us", "-o", tmp_path / "cli.npz")
    seen = []
    ds = ebiv.track(rec, time=("5ms", 12_000), slab=400, output=tmp_path / "py.npz",
                    progress=lambda done, total: seen.append((done, total)))
    assert (tmp_path / "py.npz").read_bytes() == (tmp_path / "cli.npz").read_bytes()
    assert seen and seen[-1][0] == seen[-1][1] == (vortex / "rec.raw").stat().st_size
    assert ds.t_us.min() >= rec.time_range[0] + 5_000
    same = ebiv.track(rec.read(), geometry=rec.geometry, time="5ms:12ms", slab="400us")
    assert same.attrs["source"] == "arrays"
    for name in ds.data_vars:
        np.testing.assert_array_equal(same[name].values, ds[name].values)


def test_settings_and_times_are_checked_before_reading(vortex):
    rec = vortex / "rec.raw"
    with pytest.raises(ValueError, match="invalid parameter `slabb`: unknown track setting; known: slab, min-events"):
        ebiv.track(rec, slabb="1ms")
    with pytest.raises(ValueError, match=r"invalid parameter `bin`: binning is `ebiv.bin_tracks"):
        ebiv.track(rec, bin=16)
    with pytest.raises(ValueError, match="invalid parameter `degree`"):
        ebiv.track(rec, degree=5)
    for bad in ["5ms", "5ms:x", "8ms:2ms", ("8ms", "2ms"), ("1ms",), 5]:
        with pytest.raises(ValueError, match="invalid parameter `time`"):
            ebiv.track(rec, time=bad)
    with pytest.raises(ValueError, match="invalid parameter `output`"):
        ebiv.track(rec, output=vortex / "tracks.txt")
    with pytest.raises(OSError):
        ebiv.track(rec, output=vortex / "missing" / "tracks.csv")


def test_ctrl_c_interrupts_tracking(vortex, tmp_path):
    def interrupt(done, total):
        _thread.interrupt_main()

    with pytest.raises(KeyboardInterrupt):
        ebiv.track(vortex / "rec.raw", output=tmp_path / "tracks.csv", progress=interrupt)
    assert not list(tmp_path.glob("*.partial"))


def test_binned_tracks_equal_the_command_line_s_field(vortex, tracks):
    expected = xr.open_dataset(vortex / "field.nc").load()
    field = ebiv.bin_tracks(tracks, 16, interval="10ms")  # the sensor size from the tracks
    xr.testing.assert_identical(field, expected)
    assert (tracks.attrs["sensor_width"], tracks.attrs["sensor_height"]) == ("640", "480")
    assert field.sizes["time"] >= 2 and int((field.status == 0).sum()) > 100
    # The same samples from the CSV file or as a dict of columns (no tracks' attributes).
    columns = {name: tracks[name].values for name in ("track_id", "t_us", "x", "y", "u", "v")}
    for source in (vortex / "cli.csv", columns):
        other = ebiv.bin_tracks(source, 16, interval=10_000, geometry="640x480")
        for name in expected.data_vars:
            np.testing.assert_array_equal(other[name].values, expected[name].values)
    with pytest.raises(ValueError, match="invalid parameter `geometry`"):
        ebiv.bin_tracks(columns)
    with pytest.raises(ValueError, match="invalid parameter `min_tracks`"):
        ebiv.bin_tracks(tracks, geometry=(640, 480), min_tracks=0)
    with pytest.raises(ValueError, match="invalid parameter `tracks`: no column `u`"):
        ebiv.bin_tracks({"track_id": [1], "t_us": [0], "x": [1.0], "y": [1.0]}, geometry=(8, 8))


def test_scores_equal_the_command_line_s(vortex, tracks):
    expected = json.loads((vortex / "report" / "tracks.json").read_text())
    assert ebiv.assess_tracks(vortex / "cli.csv", vortex / "truth.csv", truth_example="vortex") == expected
    assert ebiv.assess_tracks(tracks, vortex / "truth.csv", scenario="vortex") == expected
    # A real check of the tracking, not of the binding: most particles in view are followed.
    assert expected["particles"] > 300 and expected["yield_fraction"] > 0.5
    assert expected["spurious_fraction"] < 0.2 and expected["velocity_rms"] < 0.5
    with pytest.raises(ValueError, match="not both"):
        ebiv.assess_tracks(tracks, vortex / "truth.csv", scenario="vortex", truth_example="vortex")


def test_the_simulated_paths_are_the_truth_file_s(vortex, tracks):
    sim = ebiv.simulate("vortex", seed=5, duration="20ms", tracks=True)
    expected = ebiv.assess_tracks(tracks, vortex / "truth.csv", truth_example="vortex")
    assert ebiv.assess_tracks(tracks, sim, truth_example="vortex") == expected
    assert ebiv.assess_tracks(tracks, sim.tracks, truth_example="vortex") == expected
    without = ebiv.simulate("vortex", seed=5, duration="1ms")
    with pytest.raises(ValueError, match="tracks=True"):
        ebiv.assess_tracks(tracks, without)


def test_track_settings_list_the_command_line_s_flags(ebiv_bin, cli):
    settings = ebiv.track_settings()
    help_text = cli("track", "--help").stdout
    for key, entry in settings.items():
        assert f"--{key.replace('_', '-')}" in help_text
        assert f"[default: {entry['default']}]" in help_text
    assert settings["slab"]["value"] == "DUR|auto"
