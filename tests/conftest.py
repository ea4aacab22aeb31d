"""Shared runs: the Drake runs are seconds each, so a test session makes each one once."""

import dataclasses
import os
import shutil
import subprocess

import numpy as np
import pytest
from matplotlib.image import imread

from rc1_drake.config import Failure, Scenario
from rc1_drake.protocol import Session


class RunCache:
    """simulate() with one Session per Diagram build key and one run per distinct scenario."""

    def __init__(self):
        self._sessions = {}
        self._runs = {}

    def __call__(self, scenario: Scenario):
        key = repr(scenario)
        if key not in self._runs:
            from rc1_drake.diagram import build_key

            bk = build_key(scenario)
            if bk not in self._sessions:
                self._sessions[bk] = Session(scenario)
            self._runs[key] = self._sessions[bk].simulate(scenario)
        return self._runs[key]


@pytest.fixture(scope="session")
def simulate_cached():
    return RunCache()


@pytest.fixture(scope="session")
def nominal_scenario():
    return Scenario()


@pytest.fixture(scope="session")
def joint7_scenario():
    return Scenario(failures=[Failure(joint=7)])


def with_stop(scenario, **kwargs):
    return dataclasses.replace(scenario, stop=dataclasses.replace(scenario.stop, **kwargs))


def trial_samples(trial, keep):
    """`trial` with only the samples `keep` (a mask or a slice) of its time series."""
    cut = {k: getattr(trial, k)[keep] for k in ("t", "q", "head_yaw_rate")}
    if trial.camera is not None:
        cut["camera"] = trial.camera[keep]
    return dataclasses.replace(trial, **cut)


def first_seconds(trial, seconds):
    """`trial`'s samples up to `seconds` from its start."""
    return trial_samples(trial, trial.t - trial.t[0] <= seconds)


def screenshot(html, png, size=(1280, 720)) -> np.ndarray:
    """What headless Chromium (Debian's, software WebGL) shows of a page after 3 s: RGB in [0, 1]."""
    chromium = shutil.which("chromium")
    if chromium is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is missing: scripts/setup.sh installs Debian's")
        pytest.skip("no chromium here (scripts/setup.sh installs Debian's)")
    subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            f"--window-size={size[0]},{size[1]}",
            "--hide-scrollbars",
            "--virtual-time-budget=3000",
            f"--screenshot={png}",
            html.resolve().as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return imread(png)[..., :3]


OVERFLOW_SCRIPT = """<script>
const width = document.documentElement.clientWidth, out = [];
for (const e of document.body.querySelectorAll("*")) {
  const box = e.getBoundingClientRect();
  if (box.right > width + 1 || e.scrollWidth > e.clientWidth + 1) out.push(`${e.tagName}@${Math.round(box.right)}`);
}
document.body.setAttribute("data-overflow", JSON.stringify(out));
</script>"""


def overflowing(html, width: int = 1400) -> list:
    """The elements of a page that headless Chromium, `width` px wide, lays out past the page's width or that
    scroll sideways (tag@right edge): none, for a page that fits."""
    import json
    import re

    chromium = shutil.which("chromium")
    if chromium is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is missing: scripts/setup.sh installs Debian's")
        pytest.skip("no chromium here (scripts/setup.sh installs Debian's)")
    probe = html.with_name(html.stem + "-overflow.html")
    probe.write_text(html.read_text().replace("</body>", OVERFLOW_SCRIPT + "</body>"))
    done = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", f"--window-size={width},1000",
         "--virtual-time-budget=3000", "--dump-dom", probe.resolve().as_uri()],
        check=True, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    found = re.search(r'data-overflow="([^"]*)"', done.stdout)
    assert found, "the page's overflow probe did not run"
    return json.loads(found.group(1).replace("&quot;", '"'))
