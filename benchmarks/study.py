"""Cost of the paper's study on the crane: the full study, one segment's search, one resolver step.

Run: python benchmarks/study.py [--samples 100]
"""

import argparse
import time
import timeit

import numpy as np
from redundancy.initial_configuration import improved_start
from redundancy.objectives import ENERGY, VELOCITY
from redundancy.tasks import WorkCycle

from redundancy import actuator_space, load_robot
from redundancy.study import run_study


def seconds(function) -> float:
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=100)
    samples = parser.parse_args().samples
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)

    full = seconds(lambda: run_study(robot, cycle, samples=samples, progress=False))
    print(f"full study (2 objectives × 3 segments, {samples} samples): {full:8.2f} s")
    for objective in (VELOCITY, ENERGY):
        for segment in cycle.segments:
            cost = seconds(
                lambda s=segment, o=objective: improved_start(robot, s, o, "x3", samples)
            )
            print(f"one search, {objective.name:<8} segment {segment.name}: {cost:8.2f} s")

    q = robot.lower + (robot.upper - robot.lower) * np.random.default_rng(0).random(robot.n)
    y_dot = np.array([[0.5, 0.0]])
    repeat = 3000
    for objective in (VELOCITY, ENERGY):
        resolver, space = objective.resolver, actuator_space(robot, q)

        def law(r=resolver, s=space):
            return r.resolve(s, y_dot)

        def step(r=resolver):
            return r.resolve(actuator_space(robot, q), y_dot)

        only = min(timeit.repeat(law, number=repeat, repeat=5)) / repeat
        whole = min(timeit.repeat(step, number=repeat, repeat=5)) / repeat
        print(
            f"resolver {type(objective.resolver).__name__:<17} law alone {only * 1e6:7.1f} µs, "
            f"with the actuator-space evaluation {whole * 1e6:7.1f} µs per step (one state)"
        )


if __name__ == "__main__":
    main()
