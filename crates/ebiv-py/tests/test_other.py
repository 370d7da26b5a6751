"""ebiv.simulate, ebiv.piv, ebiv.assess and ebiv.write against the command line."""

import json

import numpy as np
import pytest
import xarray as xr

import ebiv


def test_simulate_gives_the_events_and_truth_of_the_command_line(cli, tmp_path):
    cli("simulate", "--example", "uniform", "--duration", "20ms", "--seed", "11",
        "-o", tmp_path / "rec.npz", "--truth", tmp_path / "truth.nc")
    sim = ebiv.simulate("uniform", duration="20ms", seed=11, tracks=True)
    expected = ebiv.open(tmp_path / "rec.npz").read()
    for column, want in zip(sim.events, expected):
        np.testing.assert_array_equal(column, want)
    assert sim.geometry == (640, 480)
    xr.testing.assert_identical(sim.truth, xr.open_dataset(tmp_path / "truth.nc").load())
    assert len(sim.tracks["id"]) > 0 and np.allclose(sim.tracks["u"], 2.0, atol=0.01)
    with pytest.raises(ValueError, match="neither an example"):
        ebiv.simulate("no-such-example")


def test_piv_of_arrays_finds_the_shift_and_equals_the_command_line(data, cli, tmp_path):
    a, b = data("piv/PIVlab_Karman_01.bmp"), data("piv/PIVlab_Karman_02.bmp")
    cli("process", "--method", "piv", "--images", a, b, "--window", "32,16",
        "-o", tmp_path / "cli.nc")
    ds = ebiv.piv(a, b, window=[32, 16])
    xr.testing.assert_identical(ds, xr.open_dataset(tmp_path / "cli.nc").load())
    rng = np.random.default_rng(1)
    image = rng.random((128, 160)).astype(np.float32) ** 8
    shifted = np.roll(image, (2, 3), axis=(0, 1))
    field = ebiv.piv(image, shifted, window=[32])
    valid = field.status.values == 0
    assert np.median(field.u.values[valid]) == pytest.approx(3.0, abs=0.05)
    assert np.median(field.v.values[valid]) == pytest.approx(2.0, abs=0.05)
    with pytest.raises(ValueError, match="at least two"):
        ebiv.piv(image)


def test_assess_equals_the_command_line(simulated, cli, tmp_path):
    rec, truth = simulated / "rec.raw", simulated / "truth.nc"
    cli("process", rec, "--window", "48,32", "-o", tmp_path / "f.nc")
    cli("assess", tmp_path / "f.nc", "--truth", truth, "-o", tmp_path / "report")
    expected = json.loads((tmp_path / "report" / "assessment.json").read_text())["assessment"]
    assert ebiv.assess(tmp_path / "f.nc", truth) == expected
    assert ebiv.assess(ebiv.process(rec, window=[48, 32]), truth) == expected
    by_example = ebiv.assess(tmp_path / "f.nc", truth_example="uniform")
    assert by_example["rms"] < 0.1


@pytest.mark.parametrize("extension", ["nc", "csv", "npz", "dat", "vtk"])
def test_write_gives_the_command_line_files(simulated, cli, tmp_path, extension):
    rec = simulated / "rec.raw"
    cli("process", rec, "--window", "48,32", "-o", tmp_path / f"cli.{extension}")
    ds = ebiv.process(rec, window=[48, 32])
    ebiv.write(ds, tmp_path / f"py.{extension}")
    produced = sorted(tmp_path.glob("py*"))
    assert produced
    for py_file in produced:
        cli_file = tmp_path / py_file.name.replace("py", "cli", 1)
        # A VTK series file names its members, which differ by that prefix.
        assert py_file.read_bytes().replace(b'"py_', b'"cli_') == cli_file.read_bytes(), py_file.name


def test_write_takes_a_dict_without_xarray(simulated, tmp_path):
    from ebiv import _dataset

    ds = ebiv.process(simulated / "rec.raw", window=[48, 32], decode_times=False)
    as_dict = {name: ds[name].values for name in list(ds.coords) + list(ds.data_vars)}
    as_dict["attrs"] = dict(ds.attrs)
    as_dict["variable_attrs"] = {n: dict(ds[n].attrs) for n in as_dict if n not in ("attrs",)}
    ebiv.write(as_dict, tmp_path / "d.nc")
    back = xr.open_dataset(tmp_path / "d.nc", decode_times=False)
    np.testing.assert_array_equal(back.u.values, ds.u.values)
    with pytest.raises(TypeError):
        _dataset.from_field([1, 2, 3])
