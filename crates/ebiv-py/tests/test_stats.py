"""ebiv.stats: flow statistics over the valid vectors, the same as the command's file."""

import numpy as np
import pytest

import ebiv


def test_stats_of_a_processed_series_match_numpy_and_the_command(simulated, cli, tmp_path):
    xr = pytest.importorskip("xarray")
    field = tmp_path / "flow.nc"
    ds = ebiv.process(simulated / "rec.raw", slab="10ms", time="::2ms", output=field,
                      decode_times=False)
    st = ebiv.stats(ds)
    valid = ds.status.values == 0
    u = np.where(valid, ds.u.values, np.nan)
    np.testing.assert_allclose(st.u_mean.values, np.nanmean(u, axis=0), rtol=1e-6)
    np.testing.assert_array_equal(st["count"].values, valid.sum(axis=0))
    np.testing.assert_allclose(st.uu.values, np.nanvar(u, axis=0, ddof=1), rtol=1e-5, atol=1e-12)
    out = tmp_path / "stats.nc"
    cli("stats", field, "-o", out)
    with xr.open_dataset(out) as written:
        for name in ["u_mean", "v_mean", "u_rms", "uv", "count"]:
            np.testing.assert_array_equal(written[name].values, st[name].values)


def test_phase_averaging_adds_a_phase_dimension(simulated):
    ds = ebiv.process(simulated / "rec.raw", slab="10ms", time="::2ms", decode_times=False)
    st = ebiv.stats(ds, period="8ms", phases=4)
    assert st.sizes["phase"] == 4
    assert st["count"].values.sum() == (ds.status.values == 0).sum()
    with pytest.raises(ValueError, match="period"):
        ebiv.stats(ds, period="-1ms")


def _evt2_with_triggers(path, first_us, triggers):
    """A small EVT 2.0 recording: 60 events 1 ms apart from `first_us`, a rising trigger
    edge at each of `triggers` and a falling one 100 µs later."""
    import struct

    words = []
    items = [(first_us + 1000 * k, "cd", k) for k in range(60)]
    items += [(t, "trigger", 1) for t in triggers] + [(t + 100, "trigger", 0) for t in triggers]
    high = None
    for t, kind, value in sorted(items):
        if t >> 6 != high:
            high = t >> 6
            words.append((0x8 << 28) | (high & 0x0FFFFFFF))
        low = (t & 0x3F) << 22
        if kind == "cd":
            words.append((0x1 << 28) | low | ((value % 30) << 11) | 3)
        else:
            words.append((0xA << 28) | low | value)
    header = b"% evt 2.0\n% format EVT2;height=8;width=32\n% end\n"
    path.write_bytes(header + struct.pack(f"<{len(words)}I", *words))


def test_phase_averaging_by_trigger(cli, tmp_path):
    pytest.importorskip("xarray")
    first = 1_000_000
    triggers = [first + 5000 + 10_000 * k for k in range(5)]
    _evt2_with_triggers(tmp_path / "rec.raw", first, triggers)
    times = first + 1000 * np.arange(1, 58)
    # u: the quarter of the trigger interval each field falls in (-100 outside the triggers).
    k = np.searchsorted(triggers, times, side="right") - 1
    inside = (k >= 0) & (k < len(triggers) - 1)
    quarter = np.where(inside, (times - np.array(triggers)[np.clip(k, 0, 4)]) // 2500, -100)
    u = np.repeat(quarter.astype(np.float32)[:, None, None], 2, axis=2)
    field = {"time": times.astype(np.float64), "y": np.array([8.0]), "x": np.array([8.0, 24.0]),
             "u": u, "v": np.zeros_like(u), "status": np.zeros(u.shape, np.int16),
             "attrs": {"time_origin_us": float(first)},
             "variable_attrs": {"x": {"units": "px"}, "y": {"units": "px"},
                                "u": {"units": "px/ms"}, "v": {"units": "px/ms"}}}
    st = ebiv.stats(field, triggers=tmp_path / "rec.raw", phases=4)
    assert st.sizes["phase"] == 4
    np.testing.assert_allclose(st.phase.values, [0.125, 0.375, 0.625, 0.875])
    np.testing.assert_array_equal(st.u_mean.values[:, 0, 0], [0, 1, 2, 3])
    np.testing.assert_array_equal(st["count"].values[:, 0, 0], [12, 8, 12, 8])
    assert st.attrs["fields_outside_triggers"] == (~inside).sum()
    ebiv.write(field, tmp_path / "flow.nc")
    cli("stats", tmp_path / "flow.nc", "--triggers", tmp_path / "rec.raw", "--phases", "4",
        "-o", tmp_path / "cli.nc")
    xr = pytest.importorskip("xarray")
    with xr.open_dataset(tmp_path / "cli.nc") as written:
        np.testing.assert_array_equal(written.u_mean.values, st.u_mean.values)
    # Fields of another recording (another first event) are refused.
    _evt2_with_triggers(tmp_path / "other.raw", first + 7_000_000, triggers)
    with pytest.raises(ValueError, match="first event"):
        ebiv.stats(field, triggers=tmp_path / "other.raw")
    with pytest.raises(ValueError, match="trigger_polarity"):
        ebiv.stats(field, triggers=tmp_path / "rec.raw", trigger_polarity="up")
