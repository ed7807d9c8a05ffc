"""The quad-control dashboard in headless Chromium against a running quad-control (TUM replay +
in-process SLAM + firmware double behind the WiFi-bridge emulator): frames appear, the fps counter
moves, the buttons change the flight state (and what the firmware receives), a click on the map
sets a waypoint that the controller reports. Screenshots go to test-artifacts/dashboard/.
Waits poll observable page state with generous deadlines (the machine is shared); nothing asserts
on timing.
"""

from __future__ import annotations

import http.client
import json
import subprocess
import time
import urllib.error
import urllib.request

from dashboard_fixtures import QuadControl

STATE_WAIT_MS = 60_000  # SLAM on a busy 2-core machine can take seconds per frame


def api_state(url: str) -> dict:
    with urllib.request.urlopen(url + "api/state", timeout=5) as r:
        return json.load(r)


def api_post(url: str, path: str, body, headers: dict | None = None) -> tuple[int, dict]:
    """POSTs JSON (a dict, or raw bytes) as the dashboard page does; returns (status, reply)."""
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    req = urllib.request.Request(
        url + path,
        data=data,
        method="POST",
        headers={"Content-Type": "application/json", **(headers or {})},
    )
    try:
        with urllib.request.urlopen(req, timeout=5) as r:
            return r.status, json.load(r)
    except urllib.error.HTTPError as e:
        return e.code, json.load(e)


def raw_request(
    url: str, method: str, path: str, headers: dict, body: bytes = b""
) -> tuple[int, bytes]:
    """One request with exactly these headers (Host included): what a foreign page's browser
    sends."""
    port = int(url.rstrip("/").rsplit(":", 1)[1])
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        for k, v in {**headers, "Content-Length": str(len(body))}.items():
            conn.putheader(k, v)
        conn.endheaders(body)
        r = conn.getresponse()
        return r.status, r.read()
    finally:
        conn.close()


def wait_for(predicate, timeout_s: float, what: str):
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        last = predicate()
        if last:
            return last
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


def test_dashboard_end_to_end(quad_control, firmware, browser, artifacts):
    double, _ = firmware
    page = browser.new_page()
    page.goto(quad_control.url)

    # GIVEN the replay runs WHEN the page loads THEN RGB and depth frames appear
    page.wait_for_function(
        "document.getElementById('rgb').naturalWidth === 640", timeout=STATE_WAIT_MS
    )
    page.wait_for_function(
        "document.getElementById('depth').naturalWidth === 640", timeout=STATE_WAIT_MS
    )
    # AND the frame counter and fps move
    page.wait_for_function(
        "parseFloat(document.getElementById('fps').textContent) > 0", timeout=STATE_WAIT_MS
    )
    first = page.text_content("#frame-seq")
    page.wait_for_function(
        f"document.getElementById('frame-seq').textContent !== {json.dumps(first)}",
        timeout=STATE_WAIT_MS,
    )
    # AND the firmware link reports a latency
    page.wait_for_function(
        "document.getElementById('lat-firmware').textContent.endsWith(')')", timeout=STATE_WAIT_MS
    )
    assert page.text_content("#state") == "disarmed"
    page.screenshot(path=str(artifacts / "01_frames.png"), full_page=True)

    # WHEN Arm is clicked THEN the controller is armed and the firmware receives arm=1 with
    # ArduCopter's arming gesture (throttle 1000 us, yaw full right 2000 us)
    page.click("#btn-arm")
    page.wait_for_function(
        "document.getElementById('state').textContent === 'armed'", timeout=10_000
    )
    wait_for(
        lambda: (c := double.last_command())
        and c["arm"] == 1
        and c["yaw"] == 2000
        and c["thr"] == 1000,
        10,
        "firmware to receive arm=1 with the arming gesture",
    )
    assert double.state == "armed"
    # AND take-off is refused while the gesture is held
    page.click("#btn-takeoff")
    page.wait_for_function(
        "document.getElementById('message').textContent.includes('gesture')", timeout=10_000
    )

    # WHEN Take off is clicked after the gesture (needs a tracked pose) THEN take-off, then hold
    page.wait_for_function(
        "document.getElementById('tracking').textContent.startsWith('tracking: yes')",
        timeout=STATE_WAIT_MS,
    )
    wait_for(
        lambda: (c := double.last_command()) and c["yaw"] == 1500, 15, "the arming gesture to end"
    )
    page.click("#btn-takeoff")
    page.wait_for_function(
        "['take-off', 'hold'].includes(document.getElementById('state').textContent)",
        timeout=10_000,
    )
    page.wait_for_function(
        "document.getElementById('state').textContent === 'hold'", timeout=STATE_WAIT_MS
    )
    page.screenshot(path=str(artifacts / "02_hold.png"), full_page=True)

    # WHEN the map is clicked 80 px right of the craft THEN the controller reports that waypoint
    before = api_state(quad_control.url)
    box = page.locator("#map").bounding_box()
    page.mouse.click(box["x"] + box["width"] / 2 + 80, box["y"] + box["height"] / 2)
    page.wait_for_function(
        "document.getElementById('waypoint').textContent !== 'none'", timeout=10_000
    )
    s = api_state(quad_control.url)
    assert s["waypoint"] is not None
    # 80 px at 0.02 m/px = 1.6 m east (+x) of where the view was centred (the craft)
    assert abs(s["waypoint"]["x_m"] - (before["pose"]["x_m"] + 1.6)) < 0.3
    assert abs(s["waypoint"]["y_m"] - before["pose"]["y_m"]) < 0.3
    assert s["state"] == "go-to-waypoint"
    page.screenshot(path=str(artifacts / "03_waypoint.png"), full_page=True)

    # WHEN a manual key is pressed THEN the setpoint moves and the controller holds again
    page.keyboard.press("r")
    page.wait_for_function(
        "document.getElementById('state').textContent === 'hold'", timeout=10_000
    )

    # WHEN hostile manual steps arrive through the API (50 m -> setpoint x 50.1,
    # 1e308 twice -> x = inf, up 1e308 -> the height loop stopped) THEN each is refused and the
    # setpoint stays finite, inside the flight envelope
    before = api_state(quad_control.url)["setpoint"]
    for body, status in [
        ({"forward_m": 50}, 409),
        ({"up_m": 100}, 409),
        ({"forward_m": 1e308}, 409),
        ({"forward_m": 1e308}, 409),
        ({"up_m": 1e308}, 409),
        ({"left_m": -1e308}, 409),
        ({"yaw_ccw_deg": 1e308}, 409),
    ]:
        code, reply = api_post(quad_control.url, "api/manual", body)
        assert (code, reply["ok"]) == (status, False), (body, code, reply)
    code, _ = api_post(quad_control.url, "api/manual", b'{"forward_m": 1e400}')  # overflows to inf
    assert code == 400
    code, _ = api_post(quad_control.url, "api/waypoint", {"x_m": 1e308, "y_m": 0})
    assert code == 409
    s = api_state(quad_control.url)
    assert s["state"] == "hold" and s["setpoint"] == before, (before, s["setpoint"])

    # WHEN Disarm is clicked in flight THEN it is refused and said so
    page.click("#btn-disarm")
    page.wait_for_function(
        "document.getElementById('message').textContent.includes('refused')", timeout=10_000
    )
    assert page.text_content("#state") == "hold"

    # WHEN Land is clicked THEN landing (a throttle ramp) starts
    page.click("#btn-land")
    page.wait_for_function(
        "document.getElementById('state').textContent === 'land'", timeout=10_000
    )
    page.screenshot(path=str(artifacts / "04_land.png"), full_page=True)

    # AND the point-cloud view and the PLY export have content
    page.wait_for_function(
        "!document.getElementById('cloud-info').textContent.startsWith('0 of')",
        timeout=STATE_WAIT_MS,
    )
    with urllib.request.urlopen(quad_control.url + "api/map.ply", timeout=10) as r:
        ply = r.read().decode()
    assert ply.startswith("ply\n") and "element vertex" in ply
    page.close()


def test_api_rejects_bad_requests(quad_control):
    def post(path: str, body: bytes) -> tuple[int, dict]:
        return api_post(quad_control.url, path, body)

    cases = [
        ("api/command", b"not json", 400),
        ("api/command", b'{"command": "fly-away"}', 409),
        ("api/waypoint", b'{"x_m": "a", "y_m": 1}', 400),
        ("api/waypoint", b'{"x_m": 1}', 400),
        ("api/manual", b'{"forward_m": "x"}', 400),
        ("api/nothing", b"{}", 404),
    ]
    for path, body, status in cases:
        code, reply = post(path, body)
        assert code == status, (path, body, reply)
        assert reply["ok"] is False and reply["error"]


def test_token_required_off_loopback_and_enforced(binary):
    # Binding a non-loopback address without a token is refused before anything starts.
    r = subprocess.run(
        [str(binary), "--no-firmware", "--bind", "0.0.0.0", "--print-config"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 2 and "token" in r.stderr
    # With a token (on loopback here) the API refuses requests that do not carry it.
    qc = QuadControl(binary, ["--no-firmware", "--port", "0", "--token", "s3cret"])
    try:
        try:
            urllib.request.urlopen(qc.url + "api/state", timeout=5)
            raise AssertionError("state served without token")
        except urllib.error.HTTPError as e:
            assert e.code == 401
        req = urllib.request.Request(qc.url + "api/state", headers={"X-Dashboard-Token": "s3cret"})
        with urllib.request.urlopen(req, timeout=5) as r:
            assert json.load(r)["state"] == "disarmed"
    finally:
        qc.stop()


def test_cross_site_requests_cannot_command_the_craft(binary):
    """On loopback without a token, a POST from a foreign page (Origin evil.example, a
    DNS-rebinding Host, a text/plain "simple request") could arm an unguarded craft. Each probe
    must be refused and leave the craft disarmed; the dashboard page's own request must still
    work."""
    qc = QuadControl(binary, ["--no-firmware", "--port", "0"])
    port = qc.url.rstrip("/").rsplit(":", 1)[1]
    arm = json.dumps({"command": "arm"}).encode()
    same = f"127.0.0.1:{port}"
    probes = [
        (
            "issue probe: text/plain, Origin and Host evil.example",
            {
                "Host": "evil.example:8080",
                "Origin": "http://evil.example",
                "Content-Type": "text/plain",
            },
            403,
        ),
        (
            "Origin evil.example",
            {"Host": same, "Origin": "http://evil.example", "Content-Type": "application/json"},
            403,
        ),
        (
            "DNS rebinding: Host evil.example, same-origin to the browser",
            {
                "Host": f"evil.example:{port}",
                "Origin": f"http://evil.example:{port}",
                "Content-Type": "application/json",
            },
            403,
        ),
        ("text/plain without Origin", {"Host": same, "Content-Type": "text/plain"}, 415),
        ("form post", {"Host": same, "Content-Type": "application/x-www-form-urlencoded"}, 415),
        (
            "Sec-Fetch-Site cross-site",
            {"Host": same, "Sec-Fetch-Site": "cross-site", "Content-Type": "application/json"},
            403,
        ),
        ("Origin null", {"Host": same, "Origin": "null", "Content-Type": "application/json"}, 403),
    ]
    try:
        for name, headers, status in probes:
            code, body = raw_request(qc.url, "POST", "/api/command", headers, arm)
            assert code == status, (name, code, body)
            assert api_state(qc.url)["state"] == "disarmed", name
        # a rebinding page cannot read the state either
        code, _ = raw_request(qc.url, "GET", "/api/state", {"Host": f"evil.example:{port}"})
        assert code == 403
        # the dashboard page's own request (same origin, JSON) still arms
        code, body = raw_request(
            qc.url,
            "POST",
            "/api/command",
            {
                "Host": same,
                "Origin": f"http://{same}",
                "Sec-Fetch-Site": "same-origin",
                "Content-Type": "application/json",
            },
            arm,
        )
        assert (code, json.loads(body)["ok"]) == (200, True)
        assert api_state(qc.url)["state"] == "armed"
        assert api_post(qc.url, "api/command", {"command": "disarm"})[0] == 200
    finally:
        qc.stop()


def test_public_bind_needs_a_strong_token(binary):
    # A public bind needs a token long and random enough to resist guessing (not a 1-character one).
    for token, ok in [
        ("x", False),
        ("s3cret", False),
        ("aaaaaaaaaaaaaaaaaaaa", False),
        ("9f86d081884c7d659a2feaa0c55ad015", True),
    ]:
        r = subprocess.run(
            [str(binary), "--no-firmware", "--bind", "0.0.0.0", "--token", token, "--print-config"],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert (r.returncode == 0) == ok, (token, r.returncode, r.stderr)
        if not ok:
            assert "token" in r.stderr
