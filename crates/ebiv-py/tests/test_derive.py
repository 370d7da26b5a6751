"""ebiv.derive: vorticity, divergence, strain rates and swirling strength, against NumPy's
gradient on the same field and the command's file; process(derive=...)."""

import numpy as np
import xarray as xr
import pytest

import ebiv


def _rotation(omega=0.05, invalid=(1, 2)):
    """A solid-body rotation on a 5 × 7 grid of step 16 px, one node invalid, as a dict
    field ebiv.write and ebiv.derive take."""
    x = 8.0 + 16.0 * np.arange(7)
    y = 8.0 + 16.0 * np.arange(5)
    xx, yy = np.meshgrid(x, y)
    u = (-omega * (yy - 40.0))[None].astype(np.float32)
    v = (omega * (xx - 56.0) + 0.001 * xx**2)[None].astype(np.float32)
    status = np.zeros(u.shape, np.int16)
    u[0][invalid] = np.nan
    v[0][invalid] = np.nan
    status[0][invalid] = 8
    units = {"x": "px", "y": "px", "u": "px/ms", "v": "px/ms"}
    return {"time": np.array([5000.0]), "y": y, "x": x, "u": u, "v": v, "status": status,
            "variable_attrs": {name: {"units": unit} for name, unit in units.items()}}


def test_derived_quantities_match_numpy_gradient(tmp_path):
    pytest.importorskip("xarray")
    field = _rotation(invalid=(4, 6))  # a corner: the interior is untouched
    ds = ebiv.derive(field, decode_times=False)
    u, v = field["u"][0].astype(np.float64), field["v"][0].astype(np.float64)
    du_dy, du_dx = np.gradient(u, field["y"], field["x"])
    dv_dy, dv_dx = np.gradient(v, field["y"], field["x"])
    # NumPy's second-order central differences and first-order edges are the same scheme;
    # compare away from the invalid corner, whose NaN spreads differently in NumPy.
    inner = np.s_[0:3, 0:5]
    expected = {
        "vorticity": dv_dx - du_dy,
        "divergence": du_dx + dv_dy,
        "e_xx": du_dx,
        "e_yy": dv_dy,
        "e_xy": 0.5 * (du_dy + dv_dx),
    }
    for name, values in expected.items():
        assert ds[name].attrs["units"] == "1/ms"
        np.testing.assert_allclose(ds[name].values[0][inner], values[inner], rtol=1e-5, atol=1e-7,
                                   err_msg=name)
    trace, det = du_dx + dv_dy, du_dx * dv_dy - du_dy * dv_dx
    swirl = np.sqrt(np.maximum(det - trace**2 / 4, 0))
    np.testing.assert_allclose(ds.swirling_strength.values[0][inner], swirl[inner], rtol=1e-5)
    assert np.isnan(ds.vorticity.values[0][4, 6]), "no value at the invalid node"
    assert "clockwise" in ds.vorticity.attrs["long_name"]


def test_invalid_vectors_are_never_zeros_and_calibration_gives_per_second(tmp_path):
    pytest.importorskip("xarray")
    field = _rotation()
    ds = ebiv.derive(field, "vorticity,swirling_strength", decode_times=False)
    w = ds.vorticity.values[0]
    assert np.isnan(w[1, 2])
    # Its left neighbour (x = 24) falls back to the backward difference to x = 8: dv/dx =
    # ω + 0.001 (24 + 8) for the quadratic term, du/dy = -ω central.
    assert abs(w[1, 1] - (0.1 + 0.001 * (24 + 8))) < 1e-6
    assert list(ds.data_vars).count("divergence") == 0
    cal = ebiv.derive(field, ["vorticity"], mm_per_px=0.05, decode_times=False)
    assert cal.vorticity.attrs["units"] == "1/s"
    np.testing.assert_allclose(cal.vorticity.values[0], w * 1000, rtol=1e-6)
    with pytest.raises(ValueError, match="curl"):
        ebiv.derive(field, "curl")


def test_derive_matches_the_command(cli, tmp_path):
    xr = pytest.importorskip("xarray")
    path = tmp_path / "rot.nc"
    ebiv.write(_rotation(), path)
    ds = ebiv.derive(path, output=tmp_path / "py.nc", decode_times=False)
    cli("derive", path, "-o", tmp_path / "cli.nc")
    with xr.open_dataset(tmp_path / "cli.nc", decode_times=False) as written:
        for name in ["vorticity", "divergence", "e_xx", "e_yy", "e_xy", "swirling_strength"]:
            np.testing.assert_array_equal(written[name].values, ds[name].values)
            assert written[name].attrs == ds[name].attrs


def test_process_derive_adds_the_variables(simulated):
    ds = ebiv.process(simulated / "rec.raw", slab="10ms", time="10ms:20ms:10ms",
                      derive=["vorticity", "divergence"], decode_times=False)
    assert {"vorticity", "divergence"} <= set(ds.data_vars)
    again = ebiv.derive(ds, "vorticity,divergence", decode_times=False)
    np.testing.assert_array_equal(again.vorticity.values, ds.vorticity.values)
    with pytest.raises(ValueError, match="derive"):
        ebiv.process(simulated / "rec.raw", derive="curl")


def test_writing_a_dataset_keeps_its_derived_quantities(simulated, tmp_path):
    ds = ebiv.process(simulated / "rec.raw", slab="10ms", time="10ms:20ms:10ms",
                      derive=["vorticity"], decode_times=False)
    for ext in ("nc", "npz", "csv"):
        out = tmp_path / f"flow.{ext}"
        ebiv.write(ds, out)
        assert b"vorticity" in out.read_bytes(), ext
    back = xr.open_dataset(tmp_path / "flow.nc", decode_times=False)
    np.testing.assert_allclose(back.vorticity.values, ds.vorticity.values, rtol=1e-6, equal_nan=True)


def test_writing_a_dataset_writes_its_derived_values_as_they_are(tmp_path):
    pytest.importorskip("xarray")
    ds = ebiv.derive(_rotation(), "vorticity,divergence", decode_times=False)
    # Values no gradient of the velocities gives: the writer must take them from the dataset.
    ds["vorticity"].values[...] = 0.125
    ebiv.write(ds, tmp_path / "w.nc")
    ebiv.write(ds, tmp_path / "w.npz")
    ebiv.write(ds, tmp_path / "w.csv")
    with xr.open_dataset(tmp_path / "w.nc", decode_times=False) as back:
        assert np.all(back.vorticity.values == 0.125)
        np.testing.assert_array_equal(back.divergence.values, ds.divergence.values)
    assert np.all(np.load(tmp_path / "w.npz")["vorticity"] == 0.125)
    table = np.genfromtxt(tmp_path / "w.csv", delimiter=",", names=True)
    assert np.all(table["vorticity_1_ms"] == 0.125)


def test_converting_a_field_file_keeps_its_derived_quantities(tmp_path):
    pytest.importorskip("xarray")
    field = _rotation()
    reference = tmp_path / "derived.nc"
    ebiv.derive(field, mm_per_px=0.05, output=reference, decode_times=False)
    for ext in ("npz", "csv", "nc"):
        source = tmp_path / f"derived.{ext}"
        ebiv.derive(field, mm_per_px=0.05, output=source, decode_times=False)
        converted = tmp_path / f"from_{ext}.nc"
        ebiv.write(source, converted)
        with xr.open_dataset(converted, decode_times=False) as got, \
                xr.open_dataset(reference, decode_times=False) as want:
            for name in ["vorticity", "divergence", "e_xx", "e_yy", "e_xy", "swirling_strength"]:
                if ext == "csv":
                    # The CSV reader takes the image columns (1/ms) and no calibration.
                    assert got[name].attrs["units"] == "1/ms"
                    np.testing.assert_allclose(got[name].values * 1000, want[name].values,
                                               rtol=1e-6, err_msg=name)
                else:
                    np.testing.assert_array_equal(got[name].values, want[name].values,
                                                  err_msg=f"{ext}: {name}")
                    assert got[name].attrs == want[name].attrs
