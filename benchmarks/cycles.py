"""What the crane's whole work cycle costs to plan and to repeat: the improved start over the
whole cycle, the per-segment plan with its corners, the drift-free periodic optimum, the return
map, and 20 repetitions of the free and of the drift-free strategy; then what the repetitions
found. Each cost is the best of ``--repeat`` runs (a shared machine's timings vary).

Run: python benchmarks/cycles.py [--repeat N] [--cycles N]
"""

import argparse
import platform
import time

import numpy as np

from redundancy import load_robot
from redundancy.planning.cycles import (
    CYCLES,
    improved_cycle_start,
    periodic_optimum,
    plan_cycle,
    repeat,
    return_map,
)
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.objectives import VELOCITY
from redundancy.study.cycles import settling_words


def best_of(count: int, function):
    """The fastest of ``count`` calls, s, and the last call's result."""
    times, result = [], None
    for _ in range(count):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per cost (best of)")
    parser.add_argument("--cycles", type=int, default=CYCLES, help="cycles per repetition")
    args = parser.parse_args()
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    n = args.repeat
    costs = {}
    costs["improved start over the whole cycle (fast search)"], search = best_of(
        n, lambda: improved_cycle_start(robot, cycle, VELOCITY)
    )
    costs["whole-cycle plan: whole-cycle start, per-segment plan, corners"], plan = best_of(
        n, lambda: plan_cycle(robot, cycle, VELOCITY)
    )
    motion = plan.motion
    costs["drift-free periodic optimum (48 then 96 intervals)"], periodic = best_of(
        n, lambda: periodic_optimum(robot, cycle, motion)
    )
    costs["return map (25 starts, one batch)"], mapped = best_of(
        n, lambda: return_map(robot, cycle, VELOCITY.resolver, "x3")
    )
    label = f"{args.cycles} repetitions"
    costs[f"{label}, free (whole-cycle improved start)"], free = best_of(
        n, lambda: repeat(robot, cycle, VELOCITY.resolver, motion.q[0, 0], args.cycles)
    )
    costs[f"{label}, drift-free (periodic optimum)"], closed = best_of(
        n, lambda: repeat(robot, cycle, periodic.laws(), periodic.start, args.cycles, "periodic")
    )
    print(
        f"HIAB 031, the paper's cycle ({cycle.duration:.2f} s), velocity objective; "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}"
    )
    print()
    print("| what | cost |")
    print("| --- | --- |")
    for name, seconds in costs.items():
        shown = f"{1e3 * seconds:.0f} ms" if seconds < 1 else f"{seconds:.2f} s"
        print(f"| {name} | {shown} |")
    per_cycle = costs[f"{label}, free (whole-cycle improved start)"] / args.cycles
    print(f"\nfree cycle: {per_cycle:.3f} s of computing per {cycle.duration:.1f} s cycle")
    print(f"whole-cycle start x3 = {search.best.values[0]:.4f}, {search.simulations} motions")
    for name, repetition in (("free", free), ("drift-free", closed)):
        largest = np.abs(repetition.drift).max(axis=1)
        first = repetition.first_violation
        print(
            f"{name}: drift per cycle {largest[0]:.3g} → {largest[-1]:.3g}, "
            f"{settling_words(repetition.settling)}; "
            + ("no stroke passed" if first is None else f"first stroke passed in cycle {first[0]}")
        )
    points = ", ".join(f"{v:.4f} (P' = {s:.3f})" for v, s, _ in mapped.fixed_points)
    print(f"return map fixed points: {points or 'none'}")
    print(
        f"periodic optimum: peak {periodic.peak:.5f} m²/s², change {100 * periodic.change:.3f} %"
        f" from 48 to 96 intervals; the free cycle's {search.best.peak:.5f}"
    )


if __name__ == "__main__":
    main()
