"""The web page in a real headless Chromium against `kerfmeter --sim serve`: it loads and shows
the device, a measurement started with its Measure button completes with the kerf and the
torque–angle curve drawn live, a plan dropped on it comes back dilated as a download, a bed map
is drawn, errors are shown, it reconnects after the server restarts, and no JavaScript error
reaches the console."""

import json
import os
import subprocess
import threading
import time
import urllib.request

import pytest
from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from conftest import ROOT, TOKEN, kerfmeter_bin

# Flags that let Debian's Chromium run headless as root in a container, without reaching out.
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--window-size=1280,1600",
]
LOAD_TIMEOUT_S = 30
RUN_TIMEOUT_S = 180


@pytest.fixture
def downloads(tmp_path):
    path = tmp_path / "downloads"
    path.mkdir()
    return path


@pytest.fixture
def browser(tmp_path, downloads):
    options = Options()
    options.binary_location = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path / 'profile'}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    options.add_experimental_option(
        "prefs",
        {"download.default_directory": str(downloads), "download.prompt_for_download": False},
    )
    service = Service(executable_path=os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver"))
    driver = webdriver.Chrome(options=options, service=service)
    driver.execute_cdp_cmd(
        "Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(downloads)}
    )
    yield driver
    driver.quit()


def wait(driver, what, timeout=LOAD_TIMEOUT_S, message=""):
    # An element the page re-renders between finding it and reading it (the history table after
    # a measurement) is looked for again at the next poll, not a failure.
    return WebDriverWait(
        driver,
        timeout,
        poll_frequency=0.1,
        ignored_exceptions=(StaleElementReferenceException,),
    ).until(lambda d: what(d), message)


def text(driver, element_id):
    return driver.find_element(By.ID, element_id).text


def attr(driver, element_id, name):
    return driver.find_element(By.ID, element_id).get_attribute(name)


def console_errors(driver):
    """The console's errors since the last call: uncaught exceptions, unhandled rejections,
    console.error, and failed loads (source "network")."""
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def js_errors(driver):
    """The console's errors since the last call but failed loads (a server that is down or
    refuses a token makes those on purpose)."""
    return [e for e in console_errors(driver) if e.get("source") != "network"]


def open_page(driver, server, query=""):
    driver.get(server.url + query)
    wait(driver, lambda d: attr(d, "link", "data-state") == "connected", message="no connection")
    wait(driver, lambda d: attr(d, "info", "data-loaded") == "true", message="no device info")


def measure(driver, server, label, samples):
    """Fill the Measure form, click Measure and wait for the kerf."""
    driver.find_element(By.ID, "label").send_keys(label)
    samples_box = driver.find_element(By.ID, "samples")
    samples_box.clear()
    samples_box.send_keys(str(samples))
    driver.find_element(By.ID, "measure").click()
    kerf_um = wait(
        driver,
        lambda d: d.execute_script("return document.getElementById('kerf')?.dataset.kerfUm"),
        timeout=RUN_TIMEOUT_S,
        message=f"no kerf; page errors: {text(driver, 'errors')!r}; server:\n{server.log()}",
    )
    return float(kerf_um)


def test_page_shows_the_device_and_measures(browser, server):
    open_page(browser, server)
    info = text(browser, "info")
    assert "Firmware" in info and "Board" in info, info
    wait(browser, lambda d: "State" in text(d, "status"), message="no status")

    # An output-shaft encoder has nothing to confirm.
    assert not browser.find_element(By.ID, "confirm-zero").is_displayed()

    kerf_um = measure(browser, server, "birch-3mm", samples=2)

    # The twin cuts 150 µm gauges by default.
    assert 100 < kerf_um < 200, kerf_um
    result = text(browser, "result")
    assert "95 % confidence interval" in result, result
    assert "birch-3mm" in result, result
    # The curve was drawn live from the progress notifications, then from the run's own log.
    assert int(attr(browser, "curve", "data-live-points")) > 0
    assert int(attr(browser, "curve", "data-points")) > 10
    assert "Torque–angle curve," in attr(browser, "curve", "aria-label")
    assert text(browser, "errors") == ""
    assert console_errors(browser) == []
    # Everything the page loaded came from the server itself: it works offline.
    loaded = browser.execute_script(
        "return performance.getEntriesByType('resource').map((e) => e.name)"
    )
    assert loaded and all(url.startswith(server.url) for url in loaded), loaded


def test_history_lists_the_measurement(browser, server):
    if "--db" not in __import__("conftest").serve_flags():
        pytest.skip("this server has no history store yet (no --db)")
    open_page(browser, server)
    measure(browser, server, "mdf-4mm", samples=1)
    newest = "#history-table tbody tr:first-child"
    wait(
        browser,
        lambda d: "mdf-4mm" in "".join(e.text for e in d.find_elements(By.CSS_SELECTOR, newest)),
        message="the measurement is not the newest history row",
    )
    assert "mdf-4mm (1)" in attr(browser, "history-chart", "aria-label")
    assert js_errors(browser) == []


def server_has(driver, method):
    """Whether the server knows `method` (it answers anything but -32601 "method not found")."""
    error = driver.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "rpc.call(arguments[0], {}).then(() => done(null), (e) => done(e.code ?? null));",
        method,
    )
    return error != -32601


def test_plan_is_dilated_by_the_last_kerf_and_downloaded(browser, server, downloads):
    open_page(browser, server)
    if not server_has(browser, "dilate"):
        pytest.skip("this server has no `dilate` method yet")
    plan = ROOT / "examples" / "box-parts.svg"
    upload = browser.find_element(By.ID, "plan-file")

    # No kerf measured yet: a clear error, shown on the page, and nothing downloaded.
    upload.send_keys(str(plan))
    wait(browser, lambda d: text(d, "errors") != "", message="no error without a kerf")
    assert not list(downloads.iterdir())

    kerf_um = measure(browser, server, "", samples=1)
    upload.send_keys(str(plan))
    link = wait(browser, lambda d: d.find_elements(By.ID, "plan-download"))[0]
    name = link.get_attribute("download")
    assert name == f"box-parts-k{round(kerf_um)}.svg"
    saved = downloads / name
    wait(browser, lambda d: saved.exists() and saved.stat().st_size > 0, message="no download")
    content = saved.read_text()
    assert "<svg" in content and content != plan.read_text()

    # The same plan dropped onto the page (a drop event carrying the file) is dilated too.
    browser.execute_script(
        "const file = new File([arguments[0]], 'dropped.svg', {type: 'image/svg+xml'});"
        "const data = new DataTransfer(); data.items.add(file);"
        "document.getElementById('drop').dispatchEvent("
        "  new DragEvent('drop', {dataTransfer: data, bubbles: true, cancelable: true}));",
        plan.read_text(),
    )
    dropped = downloads / f"dropped-k{round(kerf_um)}.svg"
    wait(browser, lambda d: dropped.exists() and dropped.stat().st_size > 0, message="no drop")
    assert dropped.read_text() == content
    assert text(browser, "errors").count("Dismiss") == 1  # the error before the measurement
    assert js_errors(browser) == []


def test_abort_stops_a_run_and_says_so(browser, server):
    open_page(browser, server)
    samples_box = browser.find_element(By.ID, "samples")
    samples_box.clear()
    samples_box.send_keys("5")
    browser.find_element(By.ID, "measure").click()
    wait(browser, lambda d: int(attr(d, "curve", "data-live-points")) > 0, message="no progress")
    assert not browser.find_element(By.ID, "measure").is_enabled()
    browser.find_element(By.ID, "abort").click()
    wait(browser, lambda d: "error -32002" in text(d, "errors"), message="no aborted error")
    wait(browser, lambda d: browser.find_element(By.ID, "measure").is_enabled(), message="stuck")
    assert not browser.find_elements(By.ID, "kerf")
    assert js_errors(browser) == []


def test_a_run_started_elsewhere_shows_on_the_page(browser, server):
    """Every page follows every run: one started over HTTP by another program draws its curve
    here and ends with its kerf."""
    open_page(browser, server)
    request = urllib.request.Request(server.url + "api/run", data=b'{"label": "http"}')
    answer = {}
    post = threading.Thread(
        target=lambda: answer.update(json.load(urllib.request.urlopen(request, timeout=120)))
    )
    post.start()
    wait(browser, lambda d: int(attr(d, "curve", "data-live-points")) > 0, message="no curve")
    assert attr(browser, "progress", "data-started-by") == "http"
    assert not browser.find_element(By.ID, "measure").is_enabled()
    post.join()
    kerf_um = wait(
        browser,
        lambda d: d.execute_script("return document.getElementById('kerf')?.dataset.kerfUm"),
    )
    assert abs(float(kerf_um) - answer["kerf_um"]) < 0.01
    assert text(browser, "errors") == ""
    assert js_errors(browser) == []


def test_bed_map_is_drawn_and_a_bad_file_refused(browser, fast_server, tmp_path):
    map_file = tmp_path / "kerf-map.json"
    subprocess.run(
        [kerfmeter_bin(), "--sim", "map", "--output", str(map_file), "--json"],
        check=True,
        capture_output=True,
    )
    open_page(browser, fast_server)
    browser.find_element(By.ID, "map-file").send_keys(str(map_file))
    cells = json.loads(map_file.read_text())["cells"]
    wait(browser, lambda d: attr(d, "map", "data-cells") == str(len(cells)), message="no map")
    assert "Bed map, 4 × 3 cells" in attr(browser, "map", "aria-label")

    bad = tmp_path / "not-a-map.json"
    bad.write_text('{"cells": []}')
    browser.find_element(By.ID, "map-file").send_keys(str(bad))
    wait(browser, lambda d: "not a kerfmeter map" in text(d, "errors"), message="no error")
    assert js_errors(browser) == []


def test_rpc_errors_and_device_notifications_are_shown(browser, fast_server):
    open_page(browser, fast_server)
    # An out-of-range sample count typed past the form's checks reaches the server, whose
    # JSON-RPC error is shown with its message and code.
    browser.execute_script("rpc.call('run_kerfmeter', {samples: 0}).catch(showError)")
    wait(browser, lambda d: "error -32602" in text(d, "errors"), message="no RPC error shown")
    browser.execute_script(
        "rpc.receive(JSON.stringify({jsonrpc: '2.0', method: 'device',"
        " params: {connected: false, message: 'port closed'}}))"
    )
    banner = browser.find_element(By.ID, "device-banner")
    assert banner.is_displayed() and "port closed" in banner.text
    assert js_errors(browser) == []


def test_a_motor_shaft_device_is_confirmed_at_its_mark_from_the_page(browser, motor_shaft_server):
    open_page(browser, motor_shaft_server)
    wait(browser, lambda d: "hub-turn-unknown" in text(d, "status"), message="no condition")
    button = browser.find_element(By.ID, "confirm-zero")
    assert button.is_displayed()
    # Dismissed, the question changes nothing; accepted, the device is told.
    button.click()
    browser.switch_to.alert.dismiss()
    time.sleep(0.5)
    assert "hub-turn-unknown" in text(browser, "status")
    button.click()
    browser.switch_to.alert.accept()
    wait(
        browser,
        lambda d: "Conditions" in text(d, "status") and "hub-turn-unknown" not in text(d, "status"),
        message="the condition stayed",
    )
    assert not browser.find_element(By.ID, "confirm-zero").is_displayed()
    assert text(browser, "errors") == ""
    assert js_errors(browser) == []


def test_page_reconnects_after_the_server_restarts(browser, fast_server):
    open_page(browser, fast_server)
    fast_server.stop()
    wait(browser, lambda d: attr(d, "link", "data-state") == "disconnected", message="no loss")
    browser.execute_script("document.getElementById('info').dataset.loaded = 'false'")
    deadline = time.monotonic() + LOAD_TIMEOUT_S
    while True:  # the port may linger briefly after the old process exits
        try:
            fast_server.start()
            break
        except pytest.fail.Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)
    wait(browser, lambda d: attr(d, "link", "data-state") == "connected", message="no reconnect")
    wait(browser, lambda d: attr(d, "info", "data-loaded") == "true", message="no info again")
    assert text(browser, "errors") == ""
    # While the server was down Chromium logged the refused connections; nothing else.
    assert js_errors(browser) == []


def test_page_passes_its_token_on(browser, token_server):
    """With a token, the page's files load without it and the page hands its own `?token=` to
    the WebSocket. The token leaves the address bar at once and stays with the tab (a reload
    still connects); a tab without it says it cannot connect."""
    open_page(browser, token_server, f"?token={TOKEN}")
    assert "Firmware" in text(browser, "info")
    assert TOKEN not in browser.current_url
    browser.refresh()
    wait(browser, lambda d: attr(d, "info", "data-loaded") == "true", message="no info on reload")
    browser.execute_script("sessionStorage.clear()")
    browser.get(token_server.url)
    wait(browser, lambda d: "wants a token" in text(d, "link"), message="no word of the token")
    assert attr(browser, "info", "data-loaded") is None
