"""The one evaluation core's costs against the targets, in one run: x, A, J_H and M_H at one
state, one control step (and pink's, as a ratio), the improved start and the bound per paper
segment, and the whole study as the command runs it.

Run: python benchmarks/core.py
Best-of-N wall times on a machine that may be shared; printed, never asserted.
"""

import subprocess
import sys
import tempfile

import numpy as np
from strategies import best_time, per_call  # the script's folder: the timing helpers

from redundancy import VELOCITY, actuator_space, global_optimum, improved_start, load_robot
from redundancy.planning.ik import inverse_kinematics
from redundancy.planning.tasks import WorkCycle


def main() -> None:
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    segment = cycle["1-2"]
    q = inverse_kinematics(robot, segment.start, ["x3"], np.array([[1.0]])).q[0]

    def full():
        space = actuator_space(robot, q)
        return space.x, space.A, space.J_H, space.M_H

    rows = [("x, A, J_H, M_H at one state", per_call(full, 5000) * 1e6, "µs", 30)]
    step = per_call(lambda: VELOCITY.resolver.step(robot, q, segment.velocity), 5000)
    rows.append(("one control step (step, min ẋᵀẋ)", step * 1e6, "µs", 10))
    try:
        from pink_peer import PinkResolver

        pink = PinkResolver(robot)
        target = actuator_space(robot, q).y[0] + segment.velocity * pink.time_step
        theirs = per_call(lambda: pink.control_step(q, target), 2000)
        print(f"pink's control step: {theirs * 1e6:.1f} µs, {theirs / step:.1f} × ours")
    except Exception as error:  # pink is an optional peer
        print(f"pink's step not measured: {error}")
    for s in cycle.segments:
        cost, search = best_time(lambda s=s: improved_start(robot, s, VELOCITY), 5)
        rows.append((f"improved start (fast), segment {s.name}", cost * 1e3, "ms", 10))
        cost, optimum = best_time(lambda s=s, r=search: global_optimum(robot, s, search=r), 3)
        label = f"bound, segment {s.name} (change {100 * optimum.change:.4f} %)"
        rows.append((label, cost, "s", 1))
    with tempfile.TemporaryDirectory() as out:
        command = [sys.executable, "-m", "redundancy.cli", "study", "--quiet", "--out", out]
        cost, _ = best_time(lambda: subprocess.run(command, check=True, capture_output=True), 3)
    rows.append(("redundancy study, defaults (wall, whole command)", cost, "s", 3))
    width = max(len(r[0]) for r in rows)
    print(f"{'what':<{width}}  {'measured':>10}  {'target':>8}  ratio")
    for label, value, unit, target in rows:
        ratio = value / target
        print(f"{label:<{width}}  {value:>7.3g} {unit:<2}  {target:>5} {unit:<2}  {ratio:.2f}")


if __name__ == "__main__":
    main()
