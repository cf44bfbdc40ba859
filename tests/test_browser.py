"""Browser check: the exported page really draws the robot in headless Chromium (WebGL through SwiftShader).

For a scene, one Viewer exports two pages: the real one, and the same page with the robot hidden (Meshcat's "visible"
property on the robot's model instance). Chromium screenshots both. The check fails on a blank or broken page (no
WebGL, a script error, a wrong camera): the real page must show many pixels of the robot's colour, the hidden one
almost none, and the two screenshots must differ. Screenshots go to out/browser-<scene>.png (and -hidden.png).

Run with `make browser-test`, which installs Chromium (Debian package `chromium`) when it is missing.
"""

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from app.scene import ROOT

OUT = ROOT / "out"
WINDOW = (800, 600)
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_browser() -> str | None:
    explicit = os.environ.get("CHROMIUM")
    if explicit:
        return shutil.which(explicit)
    return next((path for path in map(shutil.which, BROWSERS) if path), None)


pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(
        find_browser() is None,
        reason="Chromium not installed (make browser-test installs the Debian package 'chromium')",
    ),
]


def chromium_command(browser: str, page: Path, screenshot: Path, profile: str) -> list[str]:
    return [
        browser,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        # WebGL without a GPU: SwiftShader, asked for explicitly (Chromium is retiring the silent fallback).
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        # Offline and quiet: no network, no updates, no first-run work, a fresh profile.
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-extensions",
        "--hide-scrollbars",
        f"--user-data-dir={profile}",
        f"--window-size={WINDOW[0]},{WINDOW[1]}",
        "--virtual-time-budget=4000",
        f"--screenshot={screenshot}",
        page.as_uri(),
    ]


def screenshot_all(pages: dict[Path, Path], attempts: int = 3, timeout: float = 90.0) -> None:
    """Screenshot every page in parallel (one Chromium each, fresh profiles). Headless Chromium now and then never
    finishes a page's virtual time (seen on a quiet machine too, with the same page drawing in seconds on the next
    try): a run that has written nothing after `timeout` seconds is killed and started again, up to `attempts`."""
    browser = find_browser()
    with tempfile.TemporaryDirectory(prefix="npp-chromium-") as profiles:
        todo, outputs = dict(pages), {}
        for attempt in range(attempts):
            runs = []
            for i, (page, shot) in enumerate(todo.items()):
                shot.unlink(missing_ok=True)
                command = chromium_command(browser, page, shot, os.path.join(profiles, f"{attempt}-{i}"))
                runs.append(
                    (
                        page,
                        shot,
                        subprocess.Popen(
                            command,
                            stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT,
                            text=True,
                        ),
                    )
                )
            for page, shot, run in runs:
                try:
                    outputs[page], _ = run.communicate(timeout=timeout)
                except subprocess.TimeoutExpired:
                    run.kill()
                    outputs[page], _ = run.communicate()
                if shot.is_file():
                    del todo[page]
            if not todo:
                return
        page = next(iter(todo))
        raise AssertionError(
            f"Chromium wrote no screenshot of {page.name} in {attempts} tries:\n{outputs[page][-2000:]}"
        )


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
    screenshot_all({page: shot, hidden_page: hidden_shot})

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
