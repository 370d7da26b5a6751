"""ebiv.filter and the denoising settings: the same events and counts as `ebiv filter`, the
filters' rules on hand-made events, and denoising in ebiv.process."""

import numpy as np
import pytest

import ebiv


def arrays(events):
    t, x, y = zip(*events)
    return (
        np.array(t, dtype=np.int64),
        np.array(x, dtype=np.uint16),
        np.array(y, dtype=np.uint16),
        np.ones(len(t), dtype=np.uint8),
    )


def test_correlation_keeps_events_with_a_neighbour_at_most_dt_before():
    # (5,5) at 0 supports (6,6) at exactly 1 ms; (4,5) at 2001 µs has only (5,5), 2001 µs
    # before, and (6,6) is two columns away.
    events = arrays([(0, 5, 5), (1000, 6, 6), (2001, 4, 5)])
    out = ebiv.filter(events, geometry=(10, 10), denoise="correlation", denoise_dt="1ms")
    assert out["events"].t.tolist() == [1000]
    assert out["removed_correlation"] == 2
    assert out["removed_refractory"] is None
    assert (out["events_in"], out["events_out"]) == (3, 1)


def test_refractory_counts_from_the_last_kept_event():
    events = arrays([(0, 1, 1), (300, 1, 1), (500, 1, 1), (900, 1, 1), (1000, 1, 1)])
    out = ebiv.filter(events, geometry=(4, 4), denoise="refractory", denoise_refractory="500us")
    assert out["events"].t.tolist() == [0, 500, 1000]
    assert out["removed_refractory"] == 2


def test_filter_writes_what_the_command_writes(tmp_path, cli):
    rec = tmp_path / "rec.raw"
    cli("simulate", "--example", "uniform", "--duration", "20ms", "--seed", "5", "-o", rec)
    mine = tmp_path / "py.csv"
    theirs = tmp_path / "cli.csv"
    counts = ebiv.filter(rec, mine, denoise="all", denoise_dt="500us")
    done = cli("filter", rec, "-o", theirs, "--denoise", "all", "--denoise-dt", "500us")
    assert mine.read_text() == theirs.read_text()
    assert "events" not in counts
    assert counts["filters"] == ["hot-pixels", "refractory", "correlation"]
    assert f"denoising kept {counts['events_out']} of {counts['events_in']} events" in done.stderr
    assert f"correlation: removed {counts['removed_correlation']} of" in done.stderr
    # Read back: the kept events, and the same from a Recording.
    kept = ebiv.open(mine).read()
    assert len(kept.t) == counts["events_out"] < counts["events_in"]
    again = ebiv.filter(ebiv.open(rec), denoise="all", denoise_dt="500us")
    assert np.array_equal(again["events"].t, kept.t)
    assert np.array_equal(again["events"].x, kept.x)


def test_process_takes_the_denoising_settings(tmp_path, cli):
    rec = tmp_path / "rec.raw"
    cli("simulate", "--example", "uniform", "--duration", "30ms", "--seed", "2", "-o", rec)
    plain = ebiv.process(rec, time="15ms:15ms:1ms")
    denoised = ebiv.process(rec, time="15ms:15ms:1ms", denoise="correlation", denoise_dt="500us")
    assert "denoise" not in plain.attrs
    assert "correlation" in denoised.attrs["denoise"]
    out = tmp_path / "f.nc"
    cli("process", rec, "--time", "15ms:15ms:1ms", "--denoise", "correlation", "--denoise-dt", "500us", "-o", out)
    import xarray as xr

    with xr.open_dataset(out) as ds:
        np.testing.assert_allclose(ds.u.values, denoised.u.values, equal_nan=True)


def test_bad_settings_name_themselves():
    events = arrays([(0, 1, 1)])
    with pytest.raises(ValueError, match="denoise"):
        ebiv.filter(events, geometry=(4, 4))
    with pytest.raises(ValueError, match="median"):
        ebiv.filter(events, geometry=(4, 4), denoise="median")
    with pytest.raises(ValueError, match="denoise-hot-factor|denoise_hot_factor"):
        ebiv.filter(events, geometry=(4, 4), denoise="hot-pixels", denoise_hot_factor=0.5)
    with pytest.raises(ValueError, match="slab"):
        ebiv.filter(events, geometry=(4, 4), denoise="all", slab="5ms")


def test_lone_hot_pixels_are_left_out_of_the_fields_as_ebiv_process_does(tmp_path, cli):
    # A sparse noisy scene with 0.1 % hot pixels at 2 kHz: kept, they give valid vectors at
    # rest where the flow is 2 px/ms.
    scenario = cli("simulate", "--print-example", "uniform").stdout
    scenario = scenario.replace('preset = "gen4"', 'preset = "noisy"\nhot_pixel_fraction = 0.001\nhot_pixel_rate_hz = 2000')
    scenario = scenario.replace("density = 0.005 ", "density = 0.0005 ").replace('duration = "20ms"', 'duration = "40ms"')
    scenario = scenario.replace("width = 640", "width = 320").replace("height = 480", "height = 240")
    path = tmp_path / "hot.toml"
    path.write_text(scenario)
    rec, truth = tmp_path / "hot.raw", tmp_path / "truth.nc"
    cli("simulate", path, "-o", rec, "--truth", truth)
    dropped = ebiv.process(rec)
    kept = ebiv.process(rec, drop_lone_pixels=False)
    lone = int(dropped.attrs["lone_pixel_events"])
    assert lone > 0
    assert "lone_pixel_events" not in kept.attrs
    rms = ebiv.assess(dropped, truth)["rms"]
    rms_kept = ebiv.assess(kept, truth)["rms"]
    assert rms < 0.05 < 4 * rms < rms_kept
    out = tmp_path / "f.nc"
    done = cli("process", rec, "-o", out)
    assert f"left out {lone} events of lone hot pixels" in done.stdout
    import xarray as xr

    with xr.open_dataset(out) as ds:
        np.testing.assert_allclose(ds.u.values, dropped.u.values, equal_nan=True)
    live = ebiv.live(rec)
    assert live["lone_pixel_events"] == lone
