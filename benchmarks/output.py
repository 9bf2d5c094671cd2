"""The study's output stage against its share of the command's time, in one run: the
command's imports, the drawing libraries' imports (paid in each of its two processes), the figures
and playback pages written from a study computed once, and the whole command.

Run: python benchmarks/output.py [--repeat N]
Best-of-N wall and CPU times on a machine that may be shared; printed, never asserted.
"""

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

from redundancy import load_robot
from redundancy.planning.angles import task_robot
from redundancy.planning.tasks import WorkCycle
from redundancy.study.study import run_study
from redundancy.viz.playback import write_playbacks
from redundancy.viz.plots import write_figures

TARGET = 3.0  # s: the whole study command
DRAWING = (  # what writing the figures and pages imports beyond the command's own imports
    "import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot, meshcat.animation, "
    "meshcat.geometry, msgpack, umsgpack, pinocchio.visualize"
)


def timed(function, repeat: int):
    """Least wall time and least CPU time (this process's and its children's) of ``repeat``
    calls (s), and the result: CPU time is what a shared machine's load disturbs least."""
    walls, cpus, result = [], [], None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), cpu_time()
        result = function()
        walls.append(time.perf_counter() - wall)
        cpus.append(cpu_time() - cpu)
    return min(walls), min(cpus), result


def cpu_time() -> float:
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def imported(statement: str, repeat: int) -> tuple[float, float]:
    """Best-of-``repeat`` wall and CPU times (s) of a fresh interpreter running ``statement``,
    less those of an empty one."""
    run = [sys.executable, "-c"]
    empty = timed(lambda: subprocess.run([*run, "pass"], check=True), repeat)
    cost = timed(lambda: subprocess.run([*run, statement], check=True), repeat)
    return cost[0] - empty[0], cost[1] - empty[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="best of (default 5)")
    repeat = parser.parse_args().repeat

    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    robot = task_robot(robot, cycle)
    *computed, study = timed(lambda: run_study(robot, cycle, progress=False), 1)
    rows = [
        ("imports of `redundancy.cli`", *imported("import redundancy.cli", repeat)),
        ("imports for drawing: matplotlib, meshcat, msgpack, ...", *imported(DRAWING, repeat)),
        ("the study computed (once, in this process)", *computed),
    ]
    with tempfile.TemporaryDirectory() as out:
        folder = Path(out)
        *cost, figures = timed(lambda: write_figures(study, folder), repeat)
        rows.append((f"write_figures ({len(figures)} PNGs)", *cost))
        *cost, pages = timed(lambda: write_playbacks(study, folder), repeat)
        rows.append((f"write_playbacks ({len(pages)} pages)", *cost))
        command = [sys.executable, "-m", "redundancy.cli", "study", "--quiet", "--out", out]
        *whole, _ = timed(lambda: subprocess.run(command, check=True, capture_output=True), 3)
    rows.append(("redundancy study, defaults (whole command, best of 3)", *whole))
    width = max(len(row[0]) for row in rows)
    print(
        f"{'what':<{width}}  {'wall':>9}  {'CPU':>9}  share of the command's wall  of {TARGET:g} s"
    )
    for label, wall, cpu in rows:
        share = f"{wall / whole[0]:>27.2f}  {wall / TARGET:>6.2f}"
        print(f"{label:<{width}}  {wall:>7.3f} s  {cpu:>7.3f} s  {share}")


if __name__ == "__main__":
    with threadpool_limits(limits=1, user_api="blas"):  # as the command runs
        main()
