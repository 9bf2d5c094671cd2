"""The evaluation core's costs against the targets, in one run: one control step beside pink's
step and two bare Pinocchio calls from Python (the floor of anything that calls Pinocchio per
step), x, A, J_H and M_H at one state and per state of a batch of 1,000, the law on that batch,
the improved start and the bound per paper segment, and the whole study as the command runs it.

Run: python benchmarks/core.py
Best-of-N wall times on a machine that may be shared; printed, never asserted. The script uses
the public API only, so the same file measures an older checkout of the package too (put it
first on PYTHONPATH).
"""

import subprocess
import sys
import tempfile

import numpy as np
import pinocchio as pin
from strategies import best_time, per_call  # the script's folder: the timing helpers

from redundancy import VELOCITY, actuator_space, global_optimum, improved_start, load_robot
from redundancy.planning.ik import inverse_kinematics
from redundancy.planning.tasks import WorkCycle

BATCH = 1000


def main() -> None:
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    segment = cycle["1-2"]
    q = inverse_kinematics(robot, segment.start, ["x3"], np.array([[1.0]])).q[0]
    rng = np.random.default_rng(0)
    batch = robot.lower + (robot.upper - robot.lower) * rng.uniform(0.2, 0.8, (BATCH, robot.n))
    y_dot = np.tile(segment.velocity, (BATCH, 1))

    def full(states):
        space = actuator_space(robot, states)
        return space.x, space.A, space.J_H, space.M_H

    step = per_call(lambda: VELOCITY.resolver.step(robot, q, segment.velocity), 5000)
    rows = [("one control step (step, min ẋᵀẋ)", step * 1e6, "µs", 2)]
    model, tool = robot.model, robot.model.getFrameId(robot.tool_frame)
    data = model.createData()

    def bare():
        pin.computeJointJacobians(model, data, q)
        return pin.getFrameJacobian(model, data, tool, pin.LOCAL_WORLD_ALIGNED)

    floor = per_call(bare, 5000)
    ratios = [f"two bare Pinocchio calls from Python: {floor * 1e6:.2f} µs, step / them = "]
    ratios[0] += f"{step / floor:.1f} (target ≤ 3)"
    try:
        from pink_peer import PinkResolver

        pink = PinkResolver(robot)
        target = actuator_space(robot, q).y[0] + segment.velocity * pink.time_step
        theirs = per_call(lambda: pink.control_step(q, target), 2000)
        ratios.append(f"pink's control step: {theirs * 1e6:.1f} µs, {theirs / step:.1f} × ours")
    except Exception as error:  # pink is an optional peer
        ratios.append(f"pink's step not measured: {error}")
    rows.append(("x, A, J_H, M_H at one state", per_call(lambda: full(q), 5000) * 1e6, "µs", 3))
    each = per_call(lambda: full(batch), 20) / BATCH
    rows.append((f"x, A, J_H, M_H, batch of {BATCH}, per state", each * 1e6, "µs", 1))
    space = actuator_space(robot, batch)
    law = per_call(lambda: VELOCITY.resolver.resolve(space, y_dot), 50) / BATCH
    rows.append((f"law on a batch of {BATCH}, per state", law * 1e6, "µs", 1))
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
    for label, value, unit, goal in rows:
        print(f"{label:<{width}}  {value:>7.3g} {unit:<2}  {goal:>5} {unit:<2}  {value / goal:.2f}")
    print("\n".join(ratios))


if __name__ == "__main__":
    main()
