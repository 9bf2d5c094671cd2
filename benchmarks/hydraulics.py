"""The hydraulic comparison on the crane's paper segments, in one run: per segment and strategy
the pump energy under load sensing and constant pressure (kJ), how far above each supply's
energy bound (%), the peak pump flow (L/min), the highest load pressure (bar) and the shortest
duration within the circuit's limits (s); then what the energy bound costs and how it
converged.

Run: python benchmarks/hydraulics.py
"""

import time

from redundancy import load_robot
from redundancy.planning.tasks import WorkCycle
from redundancy.study.study import run_study
from redundancy.viz.tables import hydraulic_table


def main() -> None:
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    costs = []
    for energy_bound in (False, True):  # the difference is what the energy bounds cost
        start = time.perf_counter()
        study = run_study(robot, cycle, progress=False, bound=False, energy_bound=energy_bound)
        costs.append(time.perf_counter() - start)
    bounds = costs[1] - costs[0]
    print(hydraulic_table(study))
    print()
    print(f"{'segment':<8}{'supply':<8}{'bound kJ':>9}  grids: energy kJ")
    for segment, found in (study.energy_bounds or {}).items():
        for supply, bound in found.items():
            grids = ", ".join(f"N={g.intervals}: {g.optimum / 1e3:.4f}" for g in bound.grids)
            print(
                f"{segment:<8}{supply:<8}{bound.energy / 1e3:>9.3f}  {grids} "
                f"(change {100 * (bound.change or 0):.2f} %)"
            )
    count = sum(len(found) for found in (study.energy_bounds or {}).values())
    print(f"energy bounds: {bounds:.1f} s for {count}, {bounds / count:.2f} s each")


if __name__ == "__main__":
    main()
