"""Browser check: the exported page really draws the robot in headless Chromium (WebGL through SwiftShader).

For a scene, one Viewer exports two pages: the real one, and the same page with the robot hidden (Meshcat's "visible"
property on the robot's model instance). Chromium screenshots both. The check fails on a blank or broken page (no
WebGL, a script error, a wrong camera): the real page must show many pixels of the robot's colour, the hidden one
almost none, and the two screenshots must differ. Screenshots go to out/browser-<scene>.png (and -hidden.png).

Run with `make browser-test`, which installs Chromium and chromedriver (Debian's `chromium`, `chromium-driver`) when
they are missing.
"""

from pathlib import Path

import numpy as np
import pytest

from app.scene.files import ROOT
from chromium import chromium, needs_chromium, screenshot_when_still

OUT = ROOT / "out"
WINDOW = (800, 600)

pytestmark = [pytest.mark.browser, needs_chromium]


def screenshot_all(pages: dict, profile) -> None:
    """Each page (path -> screenshot path) opened in one Chromium and screenshot once it stands still."""
    with chromium(profile, WINDOW) as driver:
        for page, shot in pages.items():
            driver.get(page.as_uri())
            screenshot_when_still(driver, shot)


def robot_pixels(png: Path) -> int:
    """Pixels of the robot's blue (app.viewer.ROBOT_COLOUR, shaded): blue well above red and above green.

    Nothing else in the scene is that colour: obstacles and background are grey, samples yellow/red, the path purple
    (its blue exceeds its red by only 0.2), the passage box green.
    """
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB"), int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(np.count_nonzero((b > 100) & (b - r > 70) & (b - g > 20)))


# Per scene: how far from start towards goal the recorded motion goes, and whether the robot is drawn in the default
# blue. A third of the way keeps an arm on the camera's side of the (see-through) wall in 3D scenes, so its colour is
# not blended; the quadrotor, small in a large scene, is framed at its start and must still be in the picture when
# Chromium takes it (its own colours are not the default blue, so only the change when it is hidden counts).
SCENES = {"bar": (0.3, True), "joint3d": (0.3, True), "maze": (0.01, False), "tunnel": (0.01, False)}


@pytest.mark.parametrize("scene", SCENES)
def test_exported_page_draws_the_robot_in_chromium(scene, oracles, monkeypatch, tmp_path):
    """The page frames the robot on load: it covers at least 0.15 % of the picture (the maze's camera, framing a sphere
    around the whole scene, once showed its quadrotor as a few pixels)."""
    from PIL import Image

    from app.viewer import ILLUSTRATION_PATH, ViewData, show

    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")  # Drake reads it per Meshcat; conftest says "none"
    monkeypatch.setenv("SE_OFFLINE", "true")  # Selenium Manager must not look for drivers or browsers online
    oracle = oracles(scene)
    fraction, default_colour = SCENES[scene]
    start, goal = oracle.scene.start, oracle.scene.goal
    Q = oracle.space.interpolate(start, start + fraction * (goal - start), resolution=1.0)
    times = np.linspace(0.0, 1.0, len(Q))
    viewer = show(
        oracle.scene, ViewData(times=times, positions=Q, narrow=Q[::4], on_path=np.arange(len(Q[::4])) % 2 == 0)
    )
    page, hidden_page = tmp_path / f"{scene}.html", tmp_path / f"{scene}-hidden.html"
    viewer.write_html(page)
    for name in oracle.scene.problem.robot:
        viewer.meshcat.SetProperty(f"{ILLUSTRATION_PATH}/{name}", "visible", False)
    viewer.write_html(hidden_page)

    OUT.mkdir(exist_ok=True)
    shot, hidden_shot = OUT / f"browser-{scene}.png", OUT / f"browser-{scene}-hidden.png"
    screenshot_all({page: shot, hidden_page: hidden_shot}, tmp_path / "profile")

    image = np.asarray(Image.open(shot).convert("RGB"), int)
    hidden = np.asarray(Image.open(hidden_shot).convert("RGB"), int)
    assert image.shape[:2] == (WINDOW[1], WINDOW[0])
    assert image.std() > 5, f"{shot} is blank"
    if default_colour:
        shown, not_shown = robot_pixels(shot), robot_pixels(hidden_shot)
        assert shown >= 200, f"{shot}: only {shown} robot-coloured pixels; is WebGL drawing?"
        assert not_shown <= 20, f"{hidden_shot}: {not_shown} robot-coloured pixels with the robot hidden"
    changed = np.count_nonzero(np.abs(image - hidden).sum(axis=-1) > 30)
    assert changed >= 0.0015 * image.shape[0] * image.shape[1], f"hiding the robot changed only {changed} pixels"
