"""ebiv.live: fields as they are ready, the same as process's; the live view in a real browser."""

import os
import shutil
import socket
import struct
import threading
import time
import zlib

import numpy as np
import pytest

import ebiv

SETTINGS = dict(slab="10ms", time="::5ms", window=[48, 32])


def test_live_gives_the_fields_of_process(simulated):
    rec = simulated / "rec.raw"
    fields, counts = [], []

    def on_field(dataset, stats):
        fields.append(dataset)
        counts.append(stats)

    summary = ebiv.live(rec, on_field=on_field, decode_times=False, **SETTINGS)
    expected = ebiv.process(rec, decode_times=False, **SETTINGS)
    assert summary["fields"] == len(fields) == expected.sizes["time"] > 1
    assert summary["dropped"] == 0 and not summary["stopped"]
    assert [s["fields"] for s in counts] == list(range(1, len(fields) + 1))
    for k, field in enumerate(fields):
        assert field.time.values[0] == expected.time.values[k]
        np.testing.assert_array_equal(field.u.values[0], expected.u.values[k])
        np.testing.assert_array_equal(field.status.values[0], expected.status.values[k])
    assert summary["latency_p99_ms"] >= summary["latency_p50_ms"] > 0


def test_live_output_grows_and_the_callback_stops_the_run(simulated, tmp_path):
    xr = pytest.importorskip("xarray")
    out = tmp_path / "live.nc"
    seen = []

    def on_field(dataset, stats):
        seen.append(dataset)
        return len(seen) < 2  # False after the second field: stop

    summary = ebiv.live(simulated / "rec.raw", output=out, on_field=on_field, **SETTINGS)
    assert summary["stopped"]
    with xr.open_dataset(out, decode_times=False) as written:
        assert 2 <= written.sizes["time"] < 6
        assert (written.fields_dropped.values == 0).all()
        np.testing.assert_array_equal(written.u.values[0], seen[0].u.values[0])


def test_live_refuses_bad_arguments(simulated):
    rec = simulated / "rec.raw"
    with pytest.raises(ValueError, match="follow or replay"):
        ebiv.live(rec, follow=True, replay=True)
    with pytest.raises(ValueError, match="speed"):
        ebiv.live(rec, replay=True, speed=0)
    with pytest.raises(ValueError, match="allow-remote|allow_remote"):
        ebiv.live(rec, serve="0.0.0.0:0")
    with pytest.raises(ValueError, match="piv"):
        ebiv.live(rec, method="piv")
    with pytest.raises(ValueError, match="once"):
        ebiv.live(rec, every="5ms", time="::5ms")


def test_every_is_the_step_of_time(simulated):
    rec = simulated / "rec.raw"
    times = {}
    for name, step in [("every", dict(every="5ms")), ("time", dict(time="::5ms"))]:
        seen = []
        ebiv.live(rec, slab="10ms", window=[48, 32], decode_times=False,
                  on_field=lambda ds, stats: seen.append(int(ds.time.values[0])), **step)
        times[name] = seen
    assert times["every"] == times["time"] and len(times["every"]) > 2


def _browser():
    """Headless Chromium driven by Selenium; skipped when either is missing, unless
    EBIV_BROWSER_TEST=required (as .ci/run sets it after installing them)."""
    required = os.environ.get("EBIV_BROWSER_TEST") == "required"
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver_path = shutil.which("chromedriver")
    try:
        from selenium import webdriver
    except ImportError:
        webdriver = None
    if not (chromium and driver_path and webdriver):
        message = "headless Chromium with chromedriver and selenium are needed for the live view's test"
        if required:
            pytest.fail(message)
        pytest.skip(message)
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1200,800"]:
        options.add_argument(flag)
    service = webdriver.ChromeService(executable_path=driver_path)
    return webdriver.Chrome(options=options, service=service)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _png_pixels(png: bytes) -> np.ndarray:
    """The bytes of a PNG's image data after inflating (enough to tell a blank image)."""
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    pos, data = 8, b""
    while pos < len(png):
        length, kind = struct.unpack(">I4s", png[pos:pos + 8])
        if kind == b"IDAT":
            data += png[pos + 8:pos + 8 + length]
        pos += 12 + length
    return np.frombuffer(zlib.decompress(data), dtype=np.uint8)


def test_the_live_view_draws_fields_in_a_browser(simulated, tmp_path):
    browser = _browser()
    port = _free_port()
    finished = threading.Event()
    outcome = {}

    def run():
        try:
            # 40 ms replayed at 1/400 of its rate: about 16 s, a field every 5 ms of recording.
            outcome["summary"] = ebiv.live(simulated / "rec.raw", replay=True, speed=0.0025,
                                           serve=f"127.0.0.1:{port}",
                                           on_field=lambda ds, stats: not finished.is_set(),
                                           **SETTINGS)
        except Exception as e:  # reported by the assertion below
            outcome["error"] = e

    thread = threading.Thread(target=run)
    thread.start()
    try:
        deadline = time.time() + 30
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.time() < deadline and "error" not in outcome, outcome
                time.sleep(0.1)
        browser.get(f"http://127.0.0.1:{port}/")
        from selenium.webdriver.support.ui import WebDriverWait
        WebDriverWait(browser, 60).until(
            lambda d: d.execute_script("return window.ebivLive.fieldsDrawn > 0 && window.ebivLive.imagesLoaded > 0"))
        state = browser.execute_script("return window.ebivLive")
        assert state["connected"] and state["started"] and state["vectorsDrawn"] > 20, state
        assert "corrsum" in browser.find_element("id", "description").text
        assert browser.find_element("id", "field-rate").text.endswith("/s")
        # The canvas holds the event image and the arrows: a good share of it is not black.
        lit = browser.execute_script("""
            const c = document.getElementById('view');
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let n = 0;
            for (let i = 0; i < d.length; i += 4) if (d[i] + d[i + 1] + d[i + 2] > 60) n++;
            return n / (d.length / 4);""")
        assert lit > 0.02, lit
        png = browser.get_screenshot_as_png()
        (tmp_path / "live.png").write_bytes(png)
        pixels = _png_pixels(png)
        assert len(np.unique(pixels)) > 50, "the screenshot is blank"
        # Pause freezes the drawing; resume continues it.
        browser.find_element("id", "pause").click()
        assert browser.execute_script("return window.ebivLive.paused")
        assert browser.find_element("id", "pause").text == "Resume"
        browser.find_element("id", "pause").click()
        assert not browser.execute_script("return window.ebivLive.paused")
    finally:
        finished.set()
        browser.quit()
        thread.join(120)
    assert "error" not in outcome, outcome
    assert outcome["summary"]["fields"] >= 1
