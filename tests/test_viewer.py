"""The live 3D view (issue 18 item 1), seen by a real browser.

A real ``simula -p --power-on --view`` process serves the view of its arm; headless
Chromium (Debian's ``chromium`` package, software WebGL; .ci/run installs it) loads the
page, an RCCL program turns the waist, and the same page, updated over its websocket,
is captured again. The arm is drawn in the view's orange (rcci.view.scene.ARM_COLOR): both
pictures must show a body of orange pixels, the picture must not be a uniform canvas,
and the orange must have moved. The replay (``python -m rcci.view.replay LOG --screenshot``) is
checked the same way on a shipped log. Without Chromium these tests fail and say how
to install it: they are never skipped.

Without a browser: the view's own forward kinematics from the URDF puts link 6 where
the generated kinematics does (so the drawn arm is the arm RCCL commands), and the RCCL
reader finds every queued request, draws its path through its corners and tells its
status by colour.
"""
from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import rccl
from rcci.models import load_robot
from rccl import EQ, T6, TL, gentr_rot, gentr_trsl, makeposition, yunit
from rccl.position import joint_position
from rcci.view.screenshot import Browser, pixels
from rci.simula.process import SimulaProcess

ROOT = Path(__file__).resolve().parent.parent
SIZE = (480, 360)         # small: software WebGL draws it in a third of 800 x 600's time


def orange(rgb: np.ndarray) -> np.ndarray:
    """Pixels of the arm's orange under any shading: hue 12-40 deg, saturated, not dark."""
    c = rgb.astype(float) / 255.0
    mx, mn = c.max(axis=2), c.min(axis=2)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    hue = np.degrees(np.arctan2(math.sqrt(3) * (g - b), 2 * r - g - b)) % 360
    sat = (mx - mn) / np.maximum(mx, 1e-9)
    return (hue > 12) & (hue < 40) & (sat > 0.5) & (mx > 0.3)


# viser's control panel floats at the bottom right, in the view's brand colour (the arm's
# orange) where it has a button or a slider (the replay's): its pixels are not the arm's
PANEL = (270, 200)          # its width and height (px) at SIZE, at most


def arm_orange(rgb: np.ndarray) -> np.ndarray:
    """``orange`` outside the control panel."""
    m = orange(rgb)
    m[-PANEL[1]:, -PANEL[0]:] = False
    return m


def view_line(sim: SimulaProcess, timeout: float = 30.0) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for line in list(sim.lines):
            if line.startswith("view "):
                return line.split()[1]
        time.sleep(0.05)
    raise AssertionError(f"simula --view printed no 'view URL' line: {sim.lines}")


def test_simula_view_shows_the_arm_in_chromium_and_follows_it():
    t0 = time.monotonic()
    with SimulaProcess("-p", "--power-on", "--view", "--view-port", "0", "--env", "plane:z=-0.3",
                       lockstep=True) as sim:
        url = view_line(sim)
        assert url.startswith("http://127.0.0.1:")
        with Browser(SIZE) as browser:
            browser.open(url)
            before = pixels(browser.capture())
            with rccl.open(sim.url, robot="puma260", timeout=2.0) as arm:
                q = arm.q.copy()
                q[0] += 1.4                                  # the waist turns 80 degrees
                turned = joint_position("turned", arm.kin, q)
                arm.move(turned)
                arm.waitfor(turned.end)
                reached = arm.measured_q()
            after = pixels(browser.capture())            # the same page: moved by the live updates
    assert abs(reached[0] - q[0]) < 2e-3
    for picture in (before, after):
        assert picture.shape == (SIZE[1], SIZE[0], 3)
        assert picture.reshape(-1, 3).std(axis=0).max() > 20, "a uniform canvas"
        share = arm_orange(picture).mean()
        assert share > 0.01, f"the arm's orange covers {share:.2%} of the picture"
    m0, m1 = arm_orange(before), arm_orange(after)
    overlap = (m0 & m1).sum() / (m0 | m1).sum()
    assert overlap < 0.7, f"the arm did not move in the view (orange overlap {overlap:.2f})"
    c0 = np.argwhere(m0).mean(axis=0)
    c1 = np.argwhere(m1).mean(axis=0)
    assert np.linalg.norm(c1 - c0) > 10, (c0, c1)
    print(f"simula view test: {time.monotonic() - t0:.1f} s")


def test_replay_screenshot_shows_the_arm(tmp_path):
    out = tmp_path / "replay.png"
    r = subprocess.run([sys.executable, "-m", "rcci.view.replay", "calib/logs/kinematics.rcilog.xz", "--port", "0",
                        "--screenshot", str(out), "--size", f"{SIZE[0]}x{SIZE[1]}", "--at", "20"],
                       capture_output=True, text=True, timeout=90, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert "wrote" in r.stdout
    picture = pixels(out.read_bytes())
    assert arm_orange(picture).mean() > 0.01


def test_the_replay_draws_the_collision_shapes_on_request(tmp_path):
    from rcci.view.scene import COLLISION_COLOR

    out = tmp_path / "replay-collision.png"
    r = subprocess.run([sys.executable, "-m", "rcci.view.replay", "calib/logs/kinematics.rcilog.xz", "--port", "0",
                        "--collision", "--screenshot", str(out), "--size", f"{SIZE[0]}x{SIZE[1]}", "--at", "20"],
                       capture_output=True, text=True, timeout=90, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    picture = pixels(out.read_bytes()).astype(int)
    # translucent green over the arm, the ground and the white: green above red and blue by a margin that a
    # picture without the shapes has in 0.04 % of its pixels (the same shot: 7 % with them, at 480 x 360)
    green = (picture[..., 1] - np.maximum(picture[..., 0], picture[..., 2])) > 12
    assert green.mean() > 0.02, f"{green.mean():.4f} of the picture is the shapes' green {COLLISION_COLOR}"


@pytest.mark.parametrize("robot", ["puma260", "stanford", "panda"])
def test_the_collision_shapes_ride_on_their_links(robot):
    """The view places each collision shape on its link once; at any q the link's pose times that placement is
    where rccl.collision puts the shape (what the path checks use)."""
    from rccl.collision import shape_poses
    from rcci.view.scene import ArmView

    model = load_robot(robot)
    view = ArmView(robot, port=0, collision=True)
    try:
        assert view.collision_shapes == len(view.collision_placements) > 0
        rng = np.random.default_rng(5)
        for _ in range(10):
            q = rng.uniform(model.lower, model.upper)
            poses = view.tree.link_poses(q)
            for (frame, local), shape in zip(view.collision_placements, shape_poses(robot, q)):
                assert np.allclose(poses[frame] @ local, shape.pose, atol=1e-9), shape.name
    finally:
        view.close()


@pytest.mark.parametrize("robot", ["puma260", "microbo", "panda"])
def test_the_view_draws_link_6_where_the_kinematics_put_it(robot):
    """The last link (link 6; link 7 of the Panda) where the generated fk puts it."""
    import rccl.kinematics

    from rcci.view.scene import ArmTree

    model = load_robot(robot)
    kin = rccl.kinematics.load(robot)
    tree = ArmTree(model.urdf_path, [j.name for j in model.joints])
    rng = np.random.default_rng(18)
    for _ in range(20):
        q = rng.uniform(model.lower, model.upper)
        assert np.allclose(tree.link_poses(q)[f"link{model.n_joints}"], kin.fk(q), atol=1e-9)


def _corner(name: str, x: float, y: float, z: float):
    down = gentr_rot(f"D{name}", 0.0, 0.0, 0.0, yunit, math.pi)
    return makeposition(name, T6, EQ, gentr_trsl(f"C{name}", x, y, z), down, TL, T6)


def test_the_rccl_reader_draws_every_queued_request_and_its_status():
    from rcci.view.plan import COLORS, PlanReader

    corners = [(0.30, -0.18), (0.30, 0.02), (0.20, 0.02)]
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with rccl.open(sim.url, robot="puma260", timeout=2.0) as arm:
            reader = PlanReader(arm)
            ps = [_corner(f"P{i + 1}", x, y, 0.05) for i, (x, y) in enumerate(corners)]
            arm.setvel(0.1, math.radians(60.0))
            arm.move(ps[0])
            arm.setmod("c")
            for p in ps[1:]:
                arm.move(p)
            msg = reader.sample()                       # all three queued at once, none started yet
            lines = msg["paths"]["planned"]
            assert len(lines) == 3
            for (pts, _), (x, y) in zip(lines[1:], corners[1:]):
                assert np.allclose(pts[-1], [x, y, 0.05], atol=1e-6)
            start = np.array(lines[1][0][0])
            assert np.allclose(start, [0.30, -0.18, 0.05], atol=1e-6)   # P2's line starts at P1
            arm.waitfor(ps[-1].end)
            arm.rci.wait(0.2)
            msg = reader.sample()
            assert [c for _, c in msg["paths"]["planned"]] == [list(COLORS["done"])] * 3
            assert np.allclose(np.array(msg["target"])[:3, 3], [0.20, 0.02, 0.05], atol=1e-6)
            assert "P3" in msg["status"]
            reader.detach()
            assert reader._on_transition not in arm.gen.on_transition   # noqa: SLF001


def test_the_feed_merges_what_queued_up():
    from rcci.view.process import merge

    pending: dict = {}
    merge(pending, {"q": [0] * 6, "paths": {"a": [[[[0, 0, 0], [1, 1, 1]], [1, 2, 3]]]}})
    merge(pending, {"q": [1] * 6, "paths": {"b": []}, "target": None})
    assert pending["q"] == [1] * 6 and set(pending["paths"]) == {"a", "b"} and pending["target"] is None


@pytest.mark.parametrize("cmd, needles", [
    ((sys.executable, "-m", "rcci.view.replay", "--help"), ("--port", "--screenshot", "--at", "--env", "--speed")),
    ((sys.executable, "-m", "rcci.view.process", "--help"), ("--port", "--env", "--robot")),
    ((sys.executable, "-m", "rci.simula", "--help"), ("--view", "--view-port")),
])
def test_the_view_commands_explain_themselves(cmd, needles):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    for n in needles:
        assert n in r.stdout


def test_the_view_shows_the_panda_and_its_collision_shapes(tmp_path):
    """The 7-joint Panda in the view at its ready pose, drawn from models/urdf/panda.urdf (the
    arm's orange), and with the collision shapes of models/collision/panda.toml on request (their
    translucent green over it). docs/panda-view.png was taken the same way (ArmView('panda', collision=True) at
    the ready pose, rcci.view.screenshot.screenshot at its default 1200 x 800)."""
    from rcci.view.scene import ArmView
    from rcci.view.screenshot import screenshot

    shots = {}
    for collision in (False, True):
        view = ArmView("panda", port=0, collision=collision, q=load_robot("panda").poses["ready"])
        try:
            shots[collision] = pixels(screenshot(view.url, tmp_path / f"panda-{collision}.png", size=SIZE)).astype(int)
        finally:
            view.close()
    assert arm_orange(shots[False]).mean() > 0.01
    picture = shots[True]
    green = (picture[..., 1] - np.maximum(picture[..., 0], picture[..., 2])) > 12
    assert green.mean() > 0.02
