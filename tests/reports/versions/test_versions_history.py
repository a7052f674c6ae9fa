"""The history page in headless Chromium, driven through the DevTools protocol over a pipe
(no network, no port): every chart is drawn with its points, hovering a point (a real mouse
event at its position) names it in the tooltip, clicking it filters the page to that
configuration, and "show all" restores every chart."""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import time

import pytest

import scenarios
from reports.store.results import Store
from reports.store.runs import RunSpec, blank_row, finish_time
from reports.versions.history import build_history, write_history

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: bound on every DevTools call and on waiting for the page's script
TIMEOUT_S = 30


class DevTools:
    """A minimal client of Chromium's DevTools protocol over --remote-debugging-pipe: commands
    are JSON objects terminated by NUL, written to the browser's fd 3, answers read from fd 4."""

    def __init__(self, profile, width: int, height: int):
        to_child_r, self._w = os.pipe()
        self._r, from_child_w = os.pipe()

        def fds():  # in the child, before exec: its ends become fds 3 and 4, inheritable
            # (moved above 10 first: a pipe end may itself be fd 3 or 4, and dup2 onto the same
            # number would leave it close-on-exec)
            import fcntl

            a = fcntl.fcntl(to_child_r, fcntl.F_DUPFD, 10)
            b = fcntl.fcntl(from_child_w, fcntl.F_DUPFD, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)
            os.set_inheritable(3, True)
            os.set_inheritable(4, True)

        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--remote-debugging-pipe",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", f"--user-data-dir={profile}", f"--window-size={width},{height}",
             "--hide-scrollbars", "about:blank"],
            close_fds=False, preexec_fn=fds, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )  # fmt: skip
        os.close(to_child_r)
        os.close(from_child_w)
        self._buf, self._n, self.session = b"", 0, None

    def call(self, method: str, **params):
        self._n += 1
        msg = {"id": self._n, "method": method, "params": params}
        if self.session:
            msg["sessionId"] = self.session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        end = time.monotonic() + TIMEOUT_S
        while True:
            while b"\0" in self._buf:
                raw, self._buf = self._buf.split(b"\0", 1)
                m = json.loads(raw)
                if m.get("id") == self._n:
                    assert "error" not in m, (method, m["error"])
                    return m.get("result", {})
            left = end - time.monotonic()
            assert left > 0, f"Chromium did not answer {method} within {TIMEOUT_S} s"
            if select.select([self._r], [], [], left)[0]:
                chunk = os.read(self._r, 1 << 16)
                assert chunk, "Chromium closed the pipe"
                self._buf += chunk

    def open(self, url: str) -> None:
        target = self.call("Target.createTarget", url=url)["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)[
            "sessionId"
        ]

    def js(self, expr: str):
        res = self.call("Runtime.evaluate", expression=expr, returnByValue=True)
        assert "exceptionDetails" not in res, res
        return res["result"].get("value")

    def mouse(self, kind: str, x: float, y: float) -> None:
        extra = {"button": "left", "clickCount": 1} if kind != "mouseMoved" else {}
        self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, **extra)

    def close(self) -> None:
        for fd in (self._w, self._r):
            os.close(fd)
        self.proc.kill()
        self.proc.wait(10)


def _rows(sc):
    """Two configurations over three versions; one doubles its attitude error in 1.1."""
    out = []
    for v, att in (("1.0", 1e-3), ("1.1", 3e-3), ("1.2", 3e-3)):
        for integ, scale in (("Euler", 1.0), ("RK4", 1e-6)):
            row = blank_row(RunSpec(sc, "mujoco", integ, 1e-3, engine_version=v))
            row.update(status="ok", verdict="pass", finished_at=finish_time(), nstep=1000,
                       energy_drift_max=1e-4 * scale, attitude_error_max=att * scale,
                       convergence_order=1.0 if integ == "Euler" else 4.0,
                       linear_momentum_drift_max=2e-5 * scale, joint_gap_max=1e-7 * scale,
                       branch_error=1e-6 * scale)  # fmt: skip
            out.append(row)
    return out


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hist")
    night = tmp_path_factory.mktemp("nightly")
    sc = scenarios.load("dzhanibekov")
    with Store(folder, create=True) as st:
        for r in _rows(sc):
            st.put(r)
    with Store(night, create=True) as st:  # a second folder: the history over folders
        for r in _rows(sc)[4:]:
            st.put(r)
    path = write_history([folder, night], folder / "history.html")
    return path, build_history([folder, night])


def test_page_is_self_contained(page):
    path, data = page
    text = path.read_text()
    assert "http://" not in text.replace("http://www.w3.org/2000/svg", "")
    assert "https://" not in text and "<link" not in text and "src=" not in text
    kinds = [v["axis"] for v in data["views"]]
    assert kinds == ["version", "folder"]
    (ver,) = [v for v in data["views"] if v["axis"] == "version"]
    assert ver["x"] == ["1.0", "1.1", "1.2"]
    marks = [m for c in ver["charts"] for s in c["series"] for m in s["marks"]]
    # the threefold attitude error of both configurations, 1.0 -> 1.1, and nothing else
    assert {(m["x"], m["direction"]) for m in marks} == {(1, "worse")}
    assert len(marks) == 2


def test_every_chart_names_its_unit(page):
    """Each chart's unit: a ratio's scale (energy over E_c, linear momentum over p_c), an
    angle's rad, a distance's m."""
    _, data = page
    (ver,) = [v for v in data["views"] if v["axis"] == "version"]
    units = {c["metric"]: c["unit"] for c in ver["charts"]}
    assert units == {
        "energy_drift_max": "E_c",
        "linear_momentum_drift_max": "p_c",
        "attitude_error_max": "rad",
        "joint_gap_max": "m",
        "branch_error": "rad",
    }


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_charts_render_hover_names_click_filters(page, tmp_path):
    path, data = page
    n_charts = sum(len(v["charts"]) for v in data["views"])
    n_points = [len(s["points"]) for v in data["views"] for c in v["charts"] for s in c["series"]]
    dt = DevTools(tmp_path / "profile", 1400, 900)
    try:
        dt.open(path.as_uri())
        end = time.monotonic() + TIMEOUT_S
        while dt.js("document.body && document.body.getAttribute('data-charts')") is None:
            assert time.monotonic() < end, "the page's script did not finish"
            time.sleep(0.1)
        assert int(dt.js("document.body.getAttribute('data-charts')")) == n_charts
        drawn = dt.js(
            "Array.from(document.querySelectorAll('svg.chart')).map(function (s) {"
            " var b = s.getBoundingClientRect();"
            " return [s.querySelectorAll('.pt').length, b.width, b.height]; })"
        )
        assert len(drawn) == n_charts
        assert all(p > 0 and w > 100 and h > 100 for p, w, h in drawn)
        assert sum(p for p, _, _ in drawn) == sum(n_points)
        # hover: a real mouse move to the first point of the first chart
        pt = dt.js(
            "(function () { var p = document.querySelector('svg.chart .pt');"
            " p.scrollIntoView({block: 'center'}); var b = p.getBoundingClientRect();"
            " return [b.x + b.width / 2, b.y + b.height / 2, p.getAttribute('data-label'),"
            " p.parentNode.getAttribute('data-sid')]; })()"
        )
        x, y, label, sid = pt
        assert dt.js("getComputedStyle(document.getElementById('tooltip')).display") == "none"
        dt.mouse("mouseMoved", x, y)
        assert dt.js("getComputedStyle(document.getElementById('tooltip')).display") == "block"
        tip = dt.js("document.getElementById('tooltip').textContent")
        assert tip == label and sid in tip and "version 1.0" in tip
        # click: only that configuration stays
        dt.mouse("mousePressed", x, y)
        dt.mouse("mouseReleased", x, y)
        shown = dt.js(
            "Array.from(document.querySelectorAll('svg.chart g[data-sid]')).filter(function (g)"
            " { return g.getBoundingClientRect().width > 0; }).map(function (g) {"
            " return g.getAttribute('data-sid'); })"
        )
        assert shown and set(shown) == {sid}
        visible = dt.js(
            "Array.from(document.querySelectorAll('svg.chart')).filter(function (s) {"
            " return s.getBoundingClientRect().width > 0; }).length"
        )
        assert 0 < visible < n_charts or n_charts == visible
        # show all
        dt.js("document.getElementById('showall').click()")
        assert (
            dt.js(
                "Array.from(document.querySelectorAll('svg.chart')).filter(function (s) {"
                " return s.getBoundingClientRect().width > 0; }).length"
            )
            == n_charts
        )
    finally:
        dt.close()


def test_history_refuses_a_folder_without_results(tmp_path):
    with pytest.raises(FileNotFoundError, match="no results store"):
        build_history([tmp_path])
