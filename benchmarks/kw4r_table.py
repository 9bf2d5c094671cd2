"""The 4R circle of Kazerounian & Wang three ways (docs/integral.md): the local pseudoinverse from
the default start, the improved start and the global optimum by dynamic programming, with and
without the obstacle term, on the grids given; the setting and the objectives are the suite's
(tests/test_integral_optimum.py).

Run: python benchmarks/kw4r_table.py [--grids 50,100] [--obstacle-grids 200,400]
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_integral_optimum import (  # the suite's setting, not a copy of it
    ACCELERATION,
    ARM,
    SPEED,
    SQUARED,
    WITH_OBSTACLE,
)

from redundancy import load_robot
from redundancy.planning.angles import task_robot
from redundancy.planning.tasks import WorkCycle
from redundancy.study.integral import compare


def grids(text: str) -> tuple[int, ...]:
    return tuple(int(g) for g in text.split(","))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grids", type=grids, default=(50, 100), help="intervals, ∫ q̇ᵀq̇ dt")
    parser.add_argument("--obstacle-grids", type=grids, default=(50, 100), help="the same")
    args = parser.parse_args()
    base = load_robot(ARM / "robot.toml")
    cycle = WorkCycle.from_toml(ARM / "task.toml", dimension=base.m)
    robot, circle = task_robot(base, cycle), cycle["circle"]
    print("| objective | strategy | integral | peak | max |q̇| | max |q̈| |")
    print("| --- | --- | --- | --- | --- | --- |")
    notes = []
    for label, objective, chosen in (
        ("∫ q̇ᵀq̇ dt", SQUARED, args.grids),
        ("with obstacle term", WITH_OBSTACLE, args.obstacle_grids),
    ):
        began = time.perf_counter()
        found = compare(robot, circle, objective, "x1", SPEED, ACCELERATION, grids=chosen)
        for f in found.figures:
            print(
                f"| {label} | {f.strategy} | {f.integral:.4g} | {f.peak:.4g} | {f.speed:.3g} "
                f"| {f.acceleration:.3g} |"
            )
        optimum = found.optimum
        each = ", ".join(f"{g.intervals}: {g.optimum:.4g}" for g in optimum.grids)
        notes.append(
            f"{label}: optima by grid {each}; last change {optimum.change:.2%}, converged "
            f"{optimum.converged}, acceleration binds {optimum.acceleration_binds}; "
            f"{time.perf_counter() - began:.0f} s"
        )
    print("\n".join(notes))


if __name__ == "__main__":
    main()
