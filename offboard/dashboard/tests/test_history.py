"""Dashboard history plots and the recording viewer in headless Chromium (Playwright), against a
running quad-control that records MCAP (TUM replay + in-process SLAM + firmware double).

  * live: the five uPlot charts (height vs setpoint, position error, tracking, stream fps, latency)
    fill from /api/state; the libraries come from quad-control itself (no other origin is asked);
  * recording: quad-control is stopped, its .mcap is loaded through the page's file input, the
    charts show the recorded flight, the slider scrubs and shows the recorded image at that time;
    a cut copy of the file loads up to the cut and says so.
Screenshots: test-artifacts/dashboard/history-live.png, history-recording.png.
"""

from __future__ import annotations

import pytest
from dashboard_fixtures import QuadControl, write_config

WAIT_MS = 90_000  # SLAM on a busy 2-core machine can take seconds per frame
PLOT_IDS = ["height", "poserr", "tracking", "fps", "latency"]


@pytest.fixture(scope="module")
def recording_qc(binary, firmware, tmp_path_factory):
    _, bridge = firmware
    tmp = tmp_path_factory.mktemp("qc-rec")
    cfg = write_config(tmp, bridge.port)
    qc = QuadControl(binary, ["--config", str(cfg), "--port", "0", "--record", str(tmp / "rec")])
    qc.record_dir = tmp / "rec"
    yield qc
    qc.stop()


def test_live_history_plots_fill_from_the_state(recording_qc, browser, artifacts):
    page = browser.new_page()
    foreign = []
    page.on(
        "request",
        lambda r: foreign.append(r.url) if not r.url.startswith(recording_qc.url) else None,
    )
    page.goto(recording_qc.url)
    page.click("#btn-arm")
    # Every plot drawn by uPlot (a canvas each), fed with samples that include a tracked pose and a
    # pose -> command latency (the firmware double answers, SLAM tracks the replay).
    page.wait_for_function(
        "document.querySelectorAll('#history-live .uplot canvas').length === 5", timeout=WAIT_MS
    )
    page.wait_for_function(
        "qcHistory.live.length > 10 && qcHistory.live.some(x => x.values[0][0] !== null) && "
        "qcHistory.live.some(x => x.values[4][1] !== null && x.values[4][1] !== undefined)",
        timeout=WAIT_MS,
    )
    page.wait_for_timeout(1500)  # the plots redraw once a second
    assert [
        d.get_attribute("data-plot") for d in page.query_selector_all("#history-live .plot")
    ] == PLOT_IDS
    titles = page.eval_on_selector_all(
        "#history-live .u-title", "els => els.map(e => e.textContent)"
    )
    assert titles[0].startswith("height vs setpoint") and titles[4].startswith("latency")
    assert "recording" in page.text_content("#rec-info")
    page.screenshot(path=str(artifacts / "history-live.png"), full_page=True)
    assert foreign == [], foreign  # uPlot and fzstd are served by quad-control
    page.close()


def test_a_recording_loads_and_scrubs_in_the_same_page(recording_qc, browser, artifacts, tmp_path):
    # Stop quad-control (SIGTERM by PID): the recording gets its summary.
    url = recording_qc.url
    page = browser.new_page()
    page.goto(url)
    page.wait_for_function("typeof uPlot === 'function'", timeout=WAIT_MS)
    recording_qc.stop()
    files = sorted(recording_qc.record_dir.glob("*.mcap"))
    assert len(files) == 1
    page.set_input_files("#rec-file", str(files[0]))
    page.wait_for_function(
        "qcHistory.recording && qcHistory.recording.messages > 0", timeout=WAIT_MS
    )
    rec = page.evaluate(
        "({m: qcHistory.recording.messages, end: qcHistory.recording.t_end, "
        "complete: qcHistory.recording.complete, errors: qcHistory.recording.errors, "
        "images: qcHistory.recording.images.length})"
    )
    assert rec["complete"] and rec["errors"] == [] and rec["images"] > 0 and rec["end"] > 1.0
    assert page.query_selector_all("#history-rec .uplot canvas").__len__() == 5
    # Scrub to the middle: the time label and the recorded image follow.
    mid = rec["end"] / 2
    page.eval_on_selector(
        "#rec-scrub", f"(el) => {{ el.value = '{mid}'; el.dispatchEvent(new Event('input')); }}"
    )
    # The range input snaps the value to its 0.05 s step (4.6405 -> 4.65): the scrub time is the
    # slider's value, not `mid` (an image between the two is correct; comparing with mid failed CI).
    scrub_t = float(page.eval_on_selector("#rec-scrub", "el => el.value"))
    assert abs(scrub_t - mid) <= 0.025 + 1e-9
    assert page.text_content("#rec-time") == f"t = {scrub_t:.2f} s"
    page.wait_for_function(
        "document.getElementById('rec-image').naturalWidth === 640", timeout=10_000
    )
    shown_t = float(page.get_attribute("#rec-image", "data-t"))
    # the newest image at or before the scrub time (not a later one)
    assert shown_t <= scrub_t + 1e-6
    assert shown_t >= scrub_t - 2.0, "an image from more than 2 s before the scrub time"
    page.screenshot(path=str(artifacts / "history-recording.png"), full_page=True)
    # A cut file (a crash before the summary): read up to the cut, said in the status line.
    data = files[0].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    page.set_input_files("#rec-file", str(cut))
    page.wait_for_function("qcHistory.recording.name === 'cut.mcap'", timeout=WAIT_MS)
    status = page.text_content("#rec-status")
    assert "NOT closed" in status and "truncated at byte" in status
    assert 0 < page.evaluate("qcHistory.recording.messages") < rec["m"]
    page.close()
