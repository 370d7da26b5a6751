"""ebiv.process gives what `ebiv process` gives: the same variables, values, attributes and
units, for the same settings."""

import threading
import time
import _thread

import numpy as np
import pytest
import xarray as xr

import ebiv

SETTINGS = {"window": [48, 32], "slab": "5ms", "time": "::5ms"}
FLAGS = ["--window", "48,32", "--slab", "5ms", "--time", "::5ms"]


@pytest.mark.parametrize("method", ["corrsum", "motion", "piv"])
def test_equals_the_command_line(simulated, cli, tmp_path, method):
    rec = simulated / "rec.raw"
    cli("process", rec, "--method", method, *FLAGS, "-o", tmp_path / "cli.nc")
    expected = xr.open_dataset(tmp_path / "cli.nc").load()
    ds = ebiv.process(rec, method=method, **SETTINGS)
    xr.testing.assert_identical(ds, expected)
    assert ds.u.attrs["units"] == "pixel/millisecond"
    assert int((ds.status == 0).sum()) > 0.8 * ds.status.size


def test_a_config_file_and_keywords_combine_as_on_the_command_line(simulated, cli, tmp_path):
    config = tmp_path / "ebiv.toml"
    config.write_text('window = [48, 32]\nslab = "5ms"\nmax-velocity = 8.0\nmethod = "motion"\n')
    rec = simulated / "rec.raw"
    cli("process", rec, "--config", config, "--time", "::5ms", "--no-uncertainty",
        "-o", tmp_path / "cli.nc")
    ds = ebiv.process(rec, config=config, time="::5ms", uncertainty=False,
                      output=tmp_path / "py.nc")
    expected = xr.open_dataset(tmp_path / "cli.nc").load()
    xr.testing.assert_identical(ds, expected)
    xr.testing.assert_identical(xr.open_dataset(tmp_path / "py.nc").load(), expected)
    assert np.isnan(ds.u_unc).all() and ds.attrs["method"] == "motion"
    # The file's output is written, as the command writes it.
    with_output = tmp_path / "with_output.toml"
    with_output.write_text(config.read_text() + f'output = "{tmp_path / "from_config.nc"}"\n')
    ebiv.process(rec, config=with_output, time="::5ms", uncertainty=False)
    xr.testing.assert_identical(xr.open_dataset(tmp_path / "from_config.nc").load(), expected)


def test_event_arrays_give_the_fields_of_the_file(simulated):
    rec = ebiv.open(simulated / "rec.raw")
    from_file = ebiv.process(rec.path, **SETTINGS)
    from_arrays = ebiv.process(rec.read(), geometry=rec.geometry, **SETTINGS)
    assert from_arrays.attrs["source"] == "arrays"
    for name in from_file.data_vars:
        np.testing.assert_array_equal(from_arrays[name].values, from_file[name].values)
    as_dict = ebiv.process({"t": rec.read().t, "x": rec.read().x, "y": rec.read().y,
                            "p": rec.read().p}, geometry=rec.geometry, **SETTINGS)
    np.testing.assert_array_equal(as_dict.u.values, from_file.u.values)


def test_times_stay_microseconds_when_asked(simulated):
    ds = ebiv.process(simulated / "rec.raw", decode_times=False, **SETTINGS)
    assert ds.time.dtype == np.float64
    assert ds.time.attrs["units"].startswith("microseconds since")


def test_progress_reaches_every_field(simulated):
    seen = []
    ebiv.process(simulated / "rec.raw", progress=lambda done, total: seen.append((done, total)),
                 **SETTINGS)
    assert seen and seen[-1][0] == seen[-1][1] > 1
    assert all(b >= a for (a, _), (b, _) in zip(seen, seen[1:]))


def test_an_exception_in_the_progress_callback_stops_the_run(simulated):
    def fail(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        ebiv.process(simulated / "rec.raw", progress=fail, **SETTINGS)


def test_ctrl_c_interrupts_a_long_run(simulated):
    # Ctrl-C arrives at the first field of a run of many: the run stops there.
    fields = []

    def interrupt(done, total):
        fields.append(done)
        if len(fields) == 1:
            _thread.interrupt_main()

    with pytest.raises(KeyboardInterrupt):
        ebiv.process(simulated / "rec.raw", method="motion", time="::200us", slab="5ms",
                     window=[32, 16], progress=interrupt)
    assert fields[-1] < fields[0] + 10 < 150


def test_the_gil_is_released_while_measuring(simulated):
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.005)

    thread = threading.Thread(target=tick)
    thread.start()
    started = time.monotonic()
    ebiv.process(simulated / "rec.raw", method="motion", **SETTINGS)
    elapsed = time.monotonic() - started
    stop.set()
    thread.join()
    during = [t for t in ticks if started <= t <= started + elapsed]
    # A held GIL would starve the thread for the whole call (about a second of work).
    assert elapsed > 0.2 and len(during) >= 5


def test_settings_errors_are_the_command_line_messages(simulated, cli):
    rec = simulated / "rec.raw"
    message = cli("process", rec, "--window", "0", check=False).stderr
    with pytest.raises(ValueError) as err:
        ebiv.process(rec, window=0)
    assert str(err.value) in message
    with pytest.raises(ValueError, match="unknown setting"):
        ebiv.process(rec, windw=32)
    with pytest.raises(ebiv.EbivError, match="no event"):
        ebiv.process(rec, time="5s:5.01s:1ms")
    with pytest.raises(FileNotFoundError):
        ebiv.process(rec.with_name("nothing.raw"))
    with pytest.raises(ValueError, match="length"):
        ebiv.process(tuple(np.zeros(n, dtype=np.int64) for n in (3, 2, 3, 3)))
    with pytest.raises(ValueError, match="png"):
        ebiv.process(rec, png="figures")


def test_every_setting_is_listed_with_its_default():
    settings = ebiv.settings()
    assert settings["slab"]["default"] == "10ms"
    assert "max_velocity" in settings and "uncertainty" in settings


def test_a_recording_keeps_its_reader_options(simulated, tmp_path):
    rec = ebiv.open(simulated / "rec.raw")
    # A CSV without a size: the reader options given to open() reach process().
    events = rec.read(0, 15_000)
    csv = tmp_path / "e.csv"
    np.savetxt(csv, np.column_stack(events), fmt="%d", delimiter=",", header="t,x,y,p", comments="")
    opened = ebiv.open(csv, geometry=(640, 480))
    assert opened.geometry == (640, 480)
    ds = ebiv.process(opened, window=[64, 32], slab="5ms", time="::5ms")
    direct = ebiv.process(csv, geometry="640x480", window=[64, 32], slab="5ms", time="::5ms")
    xr.testing.assert_identical(ds, direct)


def test_keywords_that_belong_elsewhere_and_bad_outputs_fail_before_the_run(simulated, tmp_path):
    rec = simulated / "rec.raw"
    for key in ("input", "images", "png"):
        with pytest.raises(ValueError, match=key):
            ebiv.process(rec, **{key: "x"})
    with pytest.raises(OSError, match="does not exist"):
        ebiv.process(rec, output=tmp_path / "missing" / "f.nc")
    with pytest.raises(ValueError, match="output"):
        ebiv.process(rec, output=tmp_path / "f.xyz")
    with pytest.raises(TypeError, match="source"):
        ebiv.process(42)
    with pytest.raises(ValueError, match="duration"):
        ebiv.open(rec).chunks(duration="-1ms")
    roi = ebiv.process(rec, roi=[0, 0, 320, 240], **SETTINGS)
    assert float(roi.x.max()) < 320 and float(roi.y.max()) < 240
