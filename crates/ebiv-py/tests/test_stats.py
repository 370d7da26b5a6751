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
