"""A screenshot of the live view (`ebiv live --serve`) while it replays a recording.

    python examples/live_view_screenshot.py ebiv-demo/vortex.raw docs/live-view.png

Needs the `ebiv` Python package, selenium, and Chromium with chromedriver (Debian:
`apt-get install chromium chromium-driver`). The recording is replayed at 1/50 of its rate
with the default settings of `ebiv process`; the page is captured once it has drawn three
fields.
"""

import shutil
import socket
import sys
import threading
import time

from selenium import webdriver
from selenium.webdriver.support.ui import WebDriverWait

import ebiv


def main(recording: str, png: str) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    finished = threading.Event()
    run = threading.Thread(target=lambda: ebiv.live(
        recording, replay=True, speed=0.02, serve=f"127.0.0.1:{port}",
        on_field=lambda dataset, stats: not finished.is_set()))
    run.start()
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or shutil.which("chromium-browser")
    for flag in ["--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                 "--disable-background-networking", "--window-size=1300,860",
                 "--force-device-scale-factor=1"]:
        options.add_argument(flag)
    browser = webdriver.Chrome(options=options,
                               service=webdriver.ChromeService(shutil.which("chromedriver")))
    try:
        for _ in range(100):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.1)
        browser.get(f"http://127.0.0.1:{port}/")
        WebDriverWait(browser, 120).until(
            lambda d: d.execute_script("return window.ebivLive.fieldsDrawn >= 3"))
        browser.save_screenshot(png)
        print(f"wrote {png}")
    finally:
        finished.set()
        browser.quit()
        run.join()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
