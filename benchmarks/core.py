"""The evaluation core's costs against the targets, in one table of one run: one control step
beside pink's step and two bare Pinocchio calls from Python (the floor of anything that calls
Pinocchio per step), x, A, J_H and M_H at one state (as the batch object `actuator_space` gives
them, and as `Controller.state` does in one compiled call) and per state of a batch of 1,000, the
law on that batch, and the improved start per paper segment, with the states its integration
evaluates at the least (a floor of its cost at a batch's price per state, x, y and J_H: what a
law reads); this checkout after an earlier tree.

Run: python benchmarks/core.py [--before DIR]
DIR is an earlier tree with its compiled core built beside its sources (e.g. `git archive REV`
extracted, with the `_core` extension of a build of REV copied into its `redundancy/`); it runs
without site hooks, as `benchmarks/study_cost.py` runs one. Each side measures itself in a
process of its own, in turn. Best-of-N wall times on a machine that may be shared; printed,
never asserted. The measuring half uses the public API only (an earlier tree without a
`Controller` steps by `Resolver.step`).
"""

import argparse
import json
import subprocess
from pathlib import Path

import numpy as np
from strategies import best_time, per_call  # the script's folder: the timing helpers
from study_cost import environment

BATCH = 1000
STAGES = 7  # states a Dormand-Prince step evaluates: six stages, and the midpoint sampled
SEGMENTS = ("1-2", "2-3", "3-1")  # the paper's, as the crane's task file names them
ROWS = [  # key, what, unit, factor from seconds, target
    ("step", "one control step (min ẋᵀẋ, crane)", "µs", 1e6, 2),
    ("pink", "pink's control step", "µs", 1e6, None),
    ("bare", "two bare Pinocchio calls from Python", "µs", 1e6, None),
    ("one", "x, A, J_H, M_H at one state (actuator_space)", "µs", 1e6, 3),
    ("state", "x, A, J_H, M_H at one state (Controller.state)", "µs", 1e6, 3),
    ("batch", f"x, A, J_H, M_H, batch of {BATCH}, per state", "µs", 1e6, 1),
    ("read", f"x, y, J_H (what a law reads), batch of {BATCH}, per state", "µs", 1e6, None),
    ("law", f"law on a batch of {BATCH}, per state", "µs", 1e6, None),
    *((f"start {s}", f"improved start (fast), segment {s}", "ms", 1e3, 10) for s in SEGMENTS),
]


def measure() -> dict[str, float]:
    """Each row's cost in seconds, with the package this interpreter imports."""
    import pinocchio as pin

    import redundancy
    from redundancy import VELOCITY, actuator_space, improved_start, load_robot
    from redundancy.planning.ik import inverse_kinematics
    from redundancy.planning.tasks import WorkCycle

    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    segment = cycle["1-2"]
    q = inverse_kinematics(robot, segment.start, ["x3"], np.array([[1.0]])).q[0]
    rng = np.random.default_rng(0)
    batch = robot.lower + (robot.upper - robot.lower) * rng.uniform(0.2, 0.8, (BATCH, robot.n))
    y_dot = np.tile(segment.velocity, (BATCH, 1))
    law = VELOCITY.resolver
    if hasattr(redundancy, "Controller"):
        controller = redundancy.Controller(robot, law)
        cost = {"step": per_call(lambda: controller.step(q, segment.velocity), 20000)}
        if hasattr(controller, "state"):
            cost["state"] = per_call(lambda: controller.state(q), 20000)
    else:
        cost = {"step": per_call(lambda: law.step(robot, q, segment.velocity), 5000)}
    model, tool = robot.model, robot.model.getFrameId(robot.tool_frame)
    data = model.createData()

    def bare():
        pin.computeJointJacobians(model, data, q)
        return pin.getFrameJacobian(model, data, tool, pin.LOCAL_WORLD_ALIGNED)

    cost["bare"] = per_call(bare, 20000)
    try:
        from pink_peer import PinkResolver

        pink = PinkResolver(robot)
        target = actuator_space(robot, q).y[0] + segment.velocity * pink.time_step
        cost["pink"] = per_call(lambda: pink.control_step(q, target), 2000)
    except ImportError:  # pink is an optional peer
        pass

    def full(states):
        space = actuator_space(robot, states)
        return space.x, space.A, space.J_H, space.M_H

    cost["one"] = per_call(lambda: full(q), 5000)
    cost["batch"] = per_call(lambda: full(batch), 20) / BATCH
    cost["read"] = per_call(lambda: actuator_space(robot, batch).J_H, 20) / BATCH
    space = actuator_space(robot, batch)
    cost["law"] = per_call(lambda: law.resolve(space, y_dot), 50) / BATCH
    for name in SEGMENTS:
        start, search = best_time(lambda s=cycle[name]: improved_start(robot, s, VELOCITY), 5)
        cost[f"start {name}"] = start
        if hasattr(search, "batches"):  # the states its integration evaluated, at the least
            steps = sum(len(motions.steps.rows) for motions in search.batches)
            cost[f"states {name}"] = STAGES * steps + search.simulations
    return cost


def run(source: Path) -> dict[str, float]:
    """`measure` in a process that imports the package from ``source``."""
    python, env = environment(source)
    command = [*python, str(Path(__file__).resolve()), "--measure"]
    out = subprocess.run(command, cwd=source, env=env, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, help="an earlier tree, its core built")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure()))
        return
    root = Path(__file__).resolve().parents[1]
    before = run(args.before.resolve()) if args.before else {}
    after = run(root)
    width = max(len(row[1]) for row in ROWS)
    print(f"{'what':<{width}}  {'before':>8}  {'after':>8}  unit  {'target':>6}  after/target")
    for key, what, unit, factor, target in ROWS:
        then, now = (
            f"{side[key] * factor:8.3g}" if key in side else " " * 8 for side in (before, after)
        )
        goal = f"{target:6g}  {after[key] * factor / target:.2f}" if target and key in after else ""
        print(f"{what:<{width}}  {then}  {now}  {unit:<4}  {goal}")
    for name, side in (("before", before), ("after", after)):
        for segment in SEGMENTS:
            if {f"states {segment}", "read"} <= side.keys():
                states = side[f"states {segment}"]
                print(
                    f"{name}: improved start {segment} integrates at least {states:,.0f} states "
                    f"({STAGES} a step and each motion's start), at {side['read'] * 1e6:.2f} µs "
                    f"each: {states * side['read'] * 1e3:.2f} ms"
                )
        if {"step", "pink", "bare"} <= side.keys():
            print(
                f"{name}: pink's step / ours {side['pink'] / side['step']:.1f} (target ≥ 25), "
                f"ours / two bare Pinocchio calls {side['step'] / side['bare']:.1f} (target ≤ 3)"
            )


if __name__ == "__main__":
    main()
