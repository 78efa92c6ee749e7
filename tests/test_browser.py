"""Headless browser test of the standalone replay page (Debian's chromium, no downloads).

The page is the standalone HTML of a hand-made hop (tests/viz_hop.py), compressed (the
default) and plain. Chromium opens it twice with a URL fragment `#t=<physical time>`
that pauses the animation there, and takes a screenshot each time. Rendering works
headless with `--disable-gpu`: WebGL falls back to SwiftShader (software GL);
`--enable-unsafe-swiftshader` keeps that fallback allowed in Chromium versions that no
longer enable it by default. `--virtual-time-budget` lets the page run its scripts
(including the asynchronous unpacking of the compressed page) before the screenshot.

The screenshots are kept under `ci-artifacts/browser/` (gitignored) for inspection.

The page's own controls (play/pause, time slider, physical-time readout) are driven by a
script added to a copy of the page, acting as a user would (slide, click), and what the
page showed is read back from `--dump-dom`.
"""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread
from viz_hop import hop_trajectory, hopper_models

from tfcontact.viz import replay

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = Path(__file__).resolve().parents[1] / "ci-artifacts" / "browser"
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--window-size=800,600",
    "--virtual-time-budget=4000",
]

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.skipif(not CHROMIUM.exists(),
                       reason="needs Debian's chromium at /usr/bin/chromium "
                              "(apt-get install chromium; .ci/run installs it)"),
]


def screenshot(page: Path, t: float, out: Path, profile: Path) -> np.ndarray:
    """Screenshot of `page` paused at physical time `t` [s]; RGB floats in [0, 1]."""
    url = page.resolve().as_uri() + f"#t={t}"
    cmd = [str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", f"--screenshot={out}", url]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0 and out.is_file(), (done.returncode, done.stderr[-2000:])
    return imread(out)[:, :, :3]


def robot_mask(image: np.ndarray) -> np.ndarray:
    """Pixels of the hopper's orange body and thigh (URDF rgba 1.0 0.45 0.0)."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (r > 0.6) & (r - b > 0.4) & (g > 0.15) & (g < 0.75 * r)


def contact_mask(image: np.ndarray) -> np.ndarray:
    """Pixels of the green 'in contact' marker (0x2ca02c)."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return (g > 0.35) & (g - r > 0.2) & (g - b > 0.2)


@pytest.mark.parametrize("compress", [True, False], ids=["compressed", "plain"])
def test_standalone_replay_draws_and_moves(tmp_path, compress):
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    stem = "hop" if compress else "hop_plain"
    page = ARTIFACTS / f"{stem}.html"
    replay(hop_trajectory(), html=page, robot=hopper_models(), compress=compress)
    times = (0.2, 0.5)  # flight (foot 0.2 m up) and stance (foot on the ground)
    shots = {}
    for t in times:
        out = ARTIFACTS / f"{stem}_t{t:.2f}.png"
        out.unlink(missing_ok=True)
        shots[t] = screenshot(page, t, out, tmp_path / f"profile-{t}")
    for t, image in shots.items():
        assert image.shape[:2] == (600, 800)
        assert robot_mask(image).mean() > 0.005, f"no robot drawn at t = {t}: blank canvas?"
    # the robot moved between the two times: the orange region's centroid shifts
    centroids = {t: np.argwhere(robot_mask(img)).mean(axis=0) for t, img in shots.items()}
    assert np.linalg.norm(centroids[0.2] - centroids[0.5]) > 10.0, centroids
    assert np.abs(shots[0.2] - shots[0.5]).max() > 0.5
    # the contact marker is green in stance only
    assert contact_mask(shots[0.5]).sum() > 20
    assert contact_mask(shots[0.2]).sum() == 0
    shutil.rmtree(tmp_path, ignore_errors=True)


# A user's moves, scripted into a copy of the page: once the replay is ready, drag the time
# slider to t = 0.5 s, press play, press pause; what the page showed after each step is
# written to an attribute of <body> that `--dump-dom` prints.
USER = """<script>
(function () {
  function run() {
    if (document.body.getAttribute("data-tfcontact-ready") !== "1") {
      setTimeout(run, 20);
      return;
    }
    var slider = document.getElementById("tfcontact-time");
    var readout = document.getElementById("tfcontact-readout");
    var button = document.getElementById("tfcontact-play");
    var seen = {bar: getComputedStyle(document.getElementById("tfcontact-controls")).display,
                max: slider.max};
    slider.value = "0.5";
    slider.dispatchEvent(new Event("input", {bubbles: true}));
    seen.slid = {readout: readout.textContent, animation: viewer.animator.time,
                 playing: viewer.animator.playing, button: button.textContent};
    button.click();
    seen.play = {playing: viewer.animator.playing, button: button.textContent};
    button.click();
    seen.pause = {playing: viewer.animator.playing, button: button.textContent};
    document.body.setAttribute("data-user", JSON.stringify(seen));
  }
  run();
})();
</script>
"""


@pytest.mark.parametrize("compress", [True, False], ids=["compressed", "plain"])
def test_replay_controls_drive_the_physical_time(tmp_path, compress):
    page = tmp_path / "hop.html"
    # half speed: the slider and the readout are in physical time, the animation is not
    replay(hop_trajectory(), html=page, robot=hopper_models(), speed=0.5, compress=compress)
    scripted = tmp_path / "hop_user.html"
    scripted.write_text(page.read_text(encoding="utf-8").replace("</body>", USER + "</body>"),
                        encoding="utf-8")
    cmd = [str(CHROMIUM), *FLAGS, f"--user-data-dir={tmp_path / 'profile'}", "--dump-dom",
           scripted.resolve().as_uri()]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr[-2000:]
    found = re.search(r'data-user="([^"]*)"', done.stdout)
    assert found, "the page never became ready: " + done.stderr[-2000:]
    seen = json.loads(html.unescape(found.group(1)))
    assert seen["bar"] == "flex" and float(seen["max"]) == pytest.approx(1.0)
    assert seen["slid"]["readout"] == "t = 0.500 s"
    assert seen["slid"]["animation"] == pytest.approx(1.0)  # 0.5 s of motion at half speed
    assert seen["slid"]["playing"] is False and seen["slid"]["button"] == "play"
    assert seen["play"] == {"playing": True, "button": "pause"}
    assert seen["pause"] == {"playing": False, "button": "play"}
