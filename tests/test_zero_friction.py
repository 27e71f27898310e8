"""examples/zero_friction.py, thesis 4.6's "zero friction" program, against a real lockstep simula:
after a push the joint keeps going (friction compensated), where zero_gravity's arm stops."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np

from rci.conversions import Conversions
from rci.session import Session
from rci.simula.process import SimulaProcess

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
CONV = Conversions.for_robot("puma260")


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _push_and_let_go(program: str) -> tuple[float, float, np.ndarray]:
    """Joint 1 pushed with 1.5 N m for 9 cycles (0.25 s at 36 Hz), then let go: its travel (deg)
    while pushed, its travel from 0.5 s to 1.5 s after, and every joint's travel (deg)."""
    with SimulaProcess("-c", "--warm", "--test-channel", lockstep=True) as sim:
        with Session(sim.url, "puma260", rate_hz=36, lock_memory=False, timeout=2.0) as s:
            f = _load("zero_friction").ZeroFriction(s) if program == "zero_friction" else _load("zero_gravity").Weightless(s)
            s.control(None, f)
            s.chg.power_on.com = 1
            assert s.wait(until=lambda: s.how.power, seconds=5)

            def after(c0: int, n: int) -> np.ndarray:
                assert s.wait(until=lambda: s.how.cycle - c0 >= n, seconds=30)
                return np.degrees(CONV.counts_to_angles(s.how.pos))

            c0, q0 = s.how.cycle, np.degrees(CONV.counts_to_angles(s.how.pos))
            assert sim.command("torque 1 1.5")["ok"]
            q1 = after(c0, 9)
            assert sim.command("torque clear")["ok"]
            c1 = s.how.cycle
            q2, q3 = after(c1, 18), after(c1, 54)
            s.release()
    return float(q1[0] - q0[0]), float(q3[0] - q2[0]), q3 - q0


def test_a_pushed_joint_keeps_going_with_zero_net_torque_and_stops_with_zero_gravity():
    pushed, coasting, travel = _push_and_let_go("zero_friction")
    assert pushed > 1.0 and coasting > 20.0, (pushed, coasting)        # "bounced around unless held"
    assert np.max(np.abs(travel[1:])) < 0.1, travel                     # the other joints stay put
    pushed_g, coasting_g, _ = _push_and_let_go("zero_gravity")
    assert pushed_g > 1.0 and abs(coasting_g) < 0.5, (pushed_g, coasting_g)   # friction stopped it


def test_zero_friction_command_line():
    r = subprocess.run([sys.executable, "examples/zero_friction.py", "--simula", "-c --warm --test-channel",
                        "--cycles", "72", "--push", "1:1.5", "--timeout", "2"], capture_output=True, text=True, timeout=120,
                       cwd=EXAMPLES.parent, stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    travel = [float(x) for x in r.stdout.split("[")[1].split("]")[0].split()]
    assert len(travel) == 6 and travel[0] > 20.0 and max(abs(x) for x in travel[1:]) < 0.1, r.stdout
