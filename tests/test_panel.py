"""The planning panel (`python -m app gui`, app/panel.py): in-process through `Panel.press`/`step`, and driven from a
real headless Chromium through Selenium.

In the browser test the panel runs as a child process with `--state FILE`; Chromium opens its page through Debian's
chromedriver (given by path: Selenium Manager is not asked to download anything), opens the controls, types a new
goal into a slider's box, presses Plan, and waits for the state file to hold the answer. The server's state must show
the value typed and a planned path; the screenshot after the plan must show the path's colour, which the one before
it lacked. Screenshots go to out/panel-<scene>-before.png and out/panel-<scene>.png.

Run the browser test with `make browser-test`, which installs Chromium and chromedriver when they are missing.
"""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from app.scene.files import ROOT
from app.viewer import PATH_COLOUR
from chromium import chromium, needs_chromium, screenshot_when_still
from meshcat_page import commands

OUT = ROOT / "out"
WINDOW = (1280, 800)  # a laptop's browser window
SCENE = "bar-3link"  # plans in about a second
GOAL_X = 70.0  # the goal's base moved 10 to the left of the scene's, still clear of the wall


def wait_for(condition, timeout: float, what: str):
    """Poll `condition` until it returns something truthy; that value, or fail naming `what`."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")


def read_state(path):
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


def path_pixels(png) -> int:
    """Pixels of the path's colour (app.viewer.PATH_COLOUR: lines are unlit, so drawn near that colour)."""
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB"), int)
    target = np.array(PATH_COLOUR[:3]) * 255
    return int(np.count_nonzero(np.abs(rgb - target).max(axis=-1) < 40))


@pytest.fixture
def panel(tmp_path):
    """The gui command serving SCENE; yields its state file. Stopped with SIGTERM, as `docker stop` would."""
    state = tmp_path / "state.json"
    env = {**os.environ, "DRAKE_ALLOW_NETWORK": "meshcat"}  # conftest says "none"; Meshcat needs its server
    server = subprocess.Popen(
        [sys.executable, "-m", "app", "gui", SCENE, "--state", str(state), "--wait", "600", "--json"],
        cwd=ROOT,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        wait_for(lambda: read_state(state) or server.poll() is not None, 60, "the panel to start")
        assert server.poll() is None, server.communicate()[1][-2000:]
        yield state, server
    finally:
        if server.poll() is None:
            server.send_signal(signal.SIGTERM)
        server.communicate(timeout=60)


@pytest.fixture
def browser(tmp_path, monkeypatch):
    monkeypatch.setenv("SE_OFFLINE", "true")  # Selenium Manager must not look for drivers or browsers online
    pytest.importorskip("selenium.webdriver")
    with chromium(tmp_path / "profile", WINDOW) as driver:
        yield driver


def control(driver, kind: str, name: str):
    """The Meshcat (dat.gui) control row of a slider ("number") or a button ("function") by its label."""
    from selenium.webdriver.common.by import By

    rows = driver.find_elements(By.XPATH, f"//li[contains(@class, '{kind}')][.//span[text()='{name}']]")
    assert len(rows) == 1, f"{len(rows)} {kind} controls named {name!r}"
    return rows[0]


@pytest.mark.browser
@needs_chromium
def test_panel_plans_in_chromium(panel, browser):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    state_path, server = panel
    state = read_state(state_path)
    assert state["last"] is None and state["start_free"] and state["goal_free"]
    browser.get(state["meshcat"])
    wait_for(lambda: browser.find_elements(By.CSS_SELECTOR, "li.cr.function"), 30, "the panel's buttons")
    browser.find_element(By.CSS_SELECTOR, ".dg.main > .close-button").click()  # "Open Controls"
    plan = control(browser, "function", "Plan")  # in view as the controls open, the scene tree unfolded
    assert plan.is_displayed() and plan.rect["y"] + plan.rect["height"] <= WINDOW[1], plan.rect
    # The scene tree folded, so that every control fits in the window (a click on a control below it would scroll).
    browser.find_element(By.XPATH, "//li[@class='title'][text()='Scene']").click()

    box = control(browser, "number", "goal base_x").find_element(By.TAG_NAME, "input")
    box.clear()
    box.send_keys(f"{GOAL_X:g}", Keys.ENTER)
    seen = wait_for(
        lambda: (s := read_state(state_path)) and s["sliders"]["goal base_x"] == GOAL_X and s,
        20,
        "the server to read the goal typed in the page",
    )
    assert seen["goal"][0] == GOAL_X and seen["goal_free"]
    OUT.mkdir(exist_ok=True)
    before = OUT / f"panel-{SCENE}-before.png"
    screenshot_when_still(browser, before)  # the goal robot redrawn where it was moved (however long that takes)

    control(browser, "function", "Plan").click()
    done = wait_for(lambda: (s := read_state(state_path)) and s["plans"] >= 1 and s, 60, "a plan")
    last = done["last"]
    assert last["success"], last
    assert last["collision_checks"] > 0 and last["goal"][0] == pytest.approx(GOAL_X)
    assert last["drawn"]["path_points"] >= 2 and last["waypoints"] >= 2
    # The page's result line is the label the server gave it.
    wait_for(
        lambda: browser.find_elements(
            By.XPATH,
            f"//span[text()='Found: {last['collision_checks']} checks, {last['seconds']:.2f} s, {last['sampler']}']",
        ),
        10,
        "the result on the page",
    )
    shot = OUT / f"panel-{SCENE}.png"
    screenshot_when_still(browser, shot)  # the path drawn

    drawn, not_drawn = path_pixels(shot), path_pixels(before)
    assert not_drawn <= 20, f"{before}: {not_drawn} path-coloured pixels before any plan"
    assert drawn >= 100, f"{shot}: only {drawn} path-coloured pixels after the plan"

    server.send_signal(signal.SIGTERM)
    out, err = server.communicate(timeout=60)
    assert server.returncode == 0, err[-2000:]
    answer = json.loads(out)
    assert answer["plans"] == 1 and answer["last"] == last


# ---- in-process: Panel.press stands for a click, Panel.step for the server loop ----------------------------------
@pytest.fixture
def make_panel(oracles, monkeypatch):
    """`make_panel(scene)`: a Panel over the session's oracle of `scene`."""
    from app.panel import Panel
    from app.planning.settings import PlanSettings

    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")
    made = []

    def make(scene: str, **options):
        made.append(Panel(oracles(scene), PlanSettings(seed=0), **options))
        return made[-1]

    yield make
    for panel in made:
        panel.close()


def settle(panel, timeout: float = 60.0) -> dict:
    """Step the panel until the worker has nothing left to do; its state then."""

    def idle():
        panel.step()
        return not panel.busy()

    wait_for(idle, timeout, "the panel's worker")
    panel.step()
    return panel.state()


def set_goal(panel, q) -> None:
    for name, value in zip(panel.state()["sliders"], [*panel.scene.start, *q]):
        panel.meshcat.SetSliderValue(name, float(value))


def test_a_new_plan_replaces_the_one_under_way(make_panel):
    panel = make_panel(SCENE)
    panel.press("Plan")
    first = panel.scene.goal.copy()
    second = first.copy()
    second[0] = GOAL_X
    set_goal(panel, second)
    panel.step()  # the server reads the sliders
    panel.press("Plan")  # while the first runs (a query takes about a second)
    assert panel.planning() and panel.state()["planning"]
    state = settle(panel)
    assert state["plans"] == 1 and state["dropped"] == 1, state
    assert state["last"]["success"] and state["last"]["goal"] == pytest.approx(second.tolist(), abs=1e-3)
    assert state["last"]["drawn"]["path_points"] == len(panel.result.trajectory.positions)
    # What is drawn is that plan's: the path, the samples (shown) and the roadmap (hidden until asked).
    html = panel.viewer.html()
    objects = {c["path"] for c in commands(html) if c["type"] == "set_object"}
    assert {"/path", "/roadmap"} <= objects and any(p.startswith("/samples/") for p in objects)


def test_the_panel_keeps_its_roadmap_between_plan_presses(make_panel):
    panel = make_panel(SCENE)
    panel.press("Plan")
    first = settle(panel)
    nodes = len(panel.cell)
    panel.press("Plan")  # the same start and goal again: answered on what the first press built
    second = settle(panel)
    assert first["last"]["success"] and second["last"]["success"]
    assert panel.result.stats.rounds == 0 and len(panel.cell) == nodes
    assert second["last"]["collision_checks"] < first["last"]["collision_checks"]


def test_buttons_cycle_the_sampler_and_toggle_what_is_shown(make_panel):
    from app.samplers import SAMPLERS

    panel = make_panel(SCENE)
    names = list(SAMPLERS)
    sampler = panel.sampler
    panel.press(f"Sampler: {sampler}")
    panel.step()
    state = panel.state()
    assert state["sampler"] == names[(names.index(sampler) + 1) % len(names)]
    assert f"Sampler: {state['sampler']}" in panel.meshcat.GetButtonNames()
    assert f"Sampler: {sampler}" not in panel.meshcat.GetButtonNames()
    panel.press("Samples: shown")
    panel.press("Roadmap: hidden")
    panel.step()
    state = panel.state()
    assert not state["samples_visible"] and state["roadmap_visible"]
    assert {"Samples: hidden", "Roadmap: shown"} <= set(panel.meshcat.GetButtonNames())
    panel.press("Play")  # nothing to play yet
    panel.step()
    assert not panel.state()["playing"]
    # The next plan uses the sampler shown; its motion plays once it is drawn.
    panel.press("Plan")
    state = settle(panel)
    assert state["last"]["sampler"] == state["sampler"] and state["playing"]


def test_a_goal_in_collision_is_flagged_and_its_plan_fails_with_moveits_code(make_panel, tmp_path):
    panel = make_panel(SCENE, state_path=tmp_path / "state.json")
    goal = panel.scene.goal.copy()
    goal[0] = 50.0  # the base inside the wall
    set_goal(panel, goal)
    panel.step()
    written = json.loads((tmp_path / "state.json").read_text())
    assert written["goal_free"] is False and written["start_free"] is True
    panel.press("Plan")
    state = settle(panel)
    assert state["last"]["success"] is False and state["last"]["error"]["code"] == "GOAL_IN_COLLISION"
    assert panel.result is None and "Failed: GOAL_IN_COLLISION" in panel.meshcat.GetButtonNames()


def test_html_export_holds_the_last_motion(make_panel, tmp_path):
    panel = make_panel(SCENE)
    panel.press("Plan")
    settle(panel)
    page = tmp_path / "panel.html"
    panel.export_html(page)
    cmds = commands(page.read_text())
    (animation,) = [c for c in cmds if c["type"] == "set_animation"]
    base = next(a["clip"] for a in animation["animations"] if a["path"].endswith("/base"))
    xs = [k["value"][0] for k in next(t for t in base["tracks"] if t["name"] == ".position")["keys"]]
    assert xs[0] == pytest.approx(panel.scene.start[0]) and xs[-1] == pytest.approx(panel.scene.goal[0])


def test_an_arms_goal_pose_is_solved_by_ik_into_the_goal_sliders(make_panel):
    from pydrake.math import RigidTransform, RollPitchYaw

    from app.planning.ik import pose_error

    panel = make_panel("window")
    names = [n for n in panel.state()["sliders"] if n.startswith("goal pose ")]
    assert len(names) == 6
    # The tool's pose at the scene's start (a free configuration, so the pose is reachable) typed into the sliders.
    plant = panel.preview.oracle.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, panel.scene.start)
    X = panel.scene.tool_frame.CalcPoseInWorld(context)
    typed = [*X.translation(), *np.degrees(RollPitchYaw(X.rotation()).vector())]
    pose = [panel.meshcat.SetSliderValue(name, value) for name, value in zip(names, typed)]
    panel.press("Goal from pose (IK)")
    state = settle(panel)
    assert state["ik"]["success"], state["ik"]
    assert state["goal"] == pytest.approx(state["ik"]["goal"], abs=1e-3)  # the sliders hold the solution
    target = RigidTransform(RollPitchYaw(np.radians(pose[3:])), pose[:3])
    position_error, angle_error = pose_error(panel.preview.oracle, np.array(state["goal"]), target)
    assert position_error < 2e-3 and angle_error < 2e-2  # the solution to IK's tolerance, rounded by the sliders


def test_the_panel_plans_what_plan_plans(make_panel, oracles):
    from app.planning.query import plan
    from app.planning.settings import PlanSettings

    panel = make_panel(SCENE)
    panel.press("Plan")
    state = settle(panel)
    direct = plan(oracles(SCENE), PlanSettings(seed=0), start=state["start"], goal=state["goal"])
    assert state["last"]["collision_checks"] == direct.collision_checks
    np.testing.assert_array_equal(panel.result.path, direct.path)


def test_moving_an_obstacle_repairs_the_panels_roadmap_and_plans_in_the_changed_cell(make_panel):
    """bar: box1 (the wall above the gap, y 54..100) moved up by 3 opens the gap to 46..57: a base at y 55.5 in the
    wall collides before the move and is free after, in the panel's own checks and in its plans."""
    panel = make_panel(SCENE)
    panel.press("Plan")
    first = settle(panel)
    assert first["last"]["success"] and first["obstacle"] == "box0" and first["changes"] == []
    panel.press("Obstacle: box0")
    panel.step()
    assert panel.state()["obstacle"] == "box1" and "Obstacle: box1" in panel.meshcat.GetButtonNames()
    goal = panel.scene.start.copy()
    goal[:3] = [50.0, 55.5, 0.0]  # in the wall, where the gap will be, the arm along x
    set_goal(panel, goal)
    panel.step()
    assert panel.state()["goal_free"] is False
    for name, value in zip(("obstacle x", "obstacle y", "obstacle z"), (0.0, 3.0, 0.0)):
        panel.meshcat.SetSliderValue(name, value)
    panel.press("Move obstacle")
    state = settle(panel)
    (change,) = state["changes"]
    assert change["success"] and change["described"] == "move box1" and change["colliding_reset"] > 0
    assert state["goal_free"] is True and panel.oracle.scene.changes and panel.result is None
    panel.press("Plan")
    state = settle(panel)
    assert state["last"]["success"] and state["last"]["certified"]
    # moving it onto the start is refused, and the panel stays in the cell it had
    start = panel.scene.start
    panel.press("Obstacle: box1")  # back to box0
    panel.step()
    for name, value in zip(("obstacle x", "obstacle y", "obstacle z"), (start[0] - 50.0, start[1] - 23.0, 0.0)):
        panel.meshcat.SetSliderValue(name, value)
    panel.press("Move obstacle")
    state = settle(panel)
    assert state["changes"][-1]["error"]["code"] == "START_STATE_IN_COLLISION"
    assert len(panel.oracle.scene.changes) == 1
    import jsonschema

    jsonschema.validate(state, json.loads((ROOT / "docs" / "schemas" / "gui.json").read_text()))
