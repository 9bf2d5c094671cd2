"""Cost of one evaluation of x, A, J_H and M_H on the crane (µs per call), alone and in batches.

Run: python benchmarks/actuator_space.py
"""

import timeit

import numpy as np

from redundancy import actuator_space, load_robot


def per_call(function, repeat: int = 7, number: int = 2000) -> float:
    """Best-of-``repeat`` seconds per call."""
    return min(timeit.repeat(function, repeat=repeat, number=number)) / number


def main() -> None:
    robot = load_robot("hiab031")
    rng = np.random.default_rng(0)
    q = robot.lower + (robot.upper - robot.lower) * rng.random(robot.n)
    v = rng.normal(size=robot.n)

    def full(states, velocities=None):
        space = actuator_space(robot, states, velocities)
        return space.x, space.A, space.J_H, space.M_H

    single = per_call(lambda: full(q))
    kinematic = per_call(lambda: actuator_space(robot, q).J_H)
    with_rates = per_call(lambda: actuator_space(robot, q, v).N_H)
    print(f"one state: x, A, J_H, M_H        {single * 1e6:8.1f} µs per call")
    print(f"one state: x, A, J_H only        {kinematic * 1e6:8.1f} µs per call")
    print(f"one state: with Ȧ and N_H        {with_rates * 1e6:8.1f} µs per call")
    for k in (10, 100, 1000):
        batch = robot.lower + (robot.upper - robot.lower) * rng.random((k, robot.n))
        cost = per_call(lambda b=batch: full(b), repeat=3, number=max(1, 20000 // k)) / k
        print(
            f"batch of {k:>4}: x, A, J_H, M_H   {cost * 1e6:8.1f} µs per state "
            f"({single / cost:.1f}x cheaper than one at a time)"
        )


if __name__ == "__main__":
    main()
