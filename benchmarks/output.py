"""The study's output stage against its share of the command's time, in one run: the
command's imports, the drawing libraries' imports (paid once by a study), the study's figures
and playback pages written from a study computed once, and the whole command.

Run: python benchmarks/output.py [--repeat N]
Best-of-N wall times on a machine that may be shared; printed, never asserted.
"""

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from strategies import best_time  # the script's folder: the timing helpers

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


def imported(statement: str, repeat: int) -> float:
    """Best-of-``repeat`` wall time (s) of a fresh interpreter running ``statement``, less that
    of an empty one."""
    run = [sys.executable, "-c"]
    empty, _ = best_time(lambda: subprocess.run([*run, "pass"], check=True), repeat)
    cost, _ = best_time(lambda: subprocess.run([*run, statement], check=True), repeat)
    return cost - empty


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="best of (default 5)")
    repeat = parser.parse_args().repeat

    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    robot = task_robot(robot, cycle)
    computed, study = best_time(lambda: run_study(robot, cycle, progress=False), 1)
    rows = [
        ("imports of `redundancy.cli`", imported("import redundancy.cli", repeat)),
        ("imports for drawing: matplotlib, meshcat, msgpack, ...", imported(DRAWING, repeat)),
        ("the study computed (once, in this process)", computed),
    ]
    with tempfile.TemporaryDirectory() as out:
        folder = Path(out)
        cost, figures = best_time(lambda: write_figures(study, folder), repeat)
        rows.append((f"write_figures ({len(figures)} PNGs)", cost))
        cost, pages = best_time(lambda: write_playbacks(study, folder), repeat)
        rows.append((f"write_playbacks ({len(pages)} pages)", cost))
        command = [sys.executable, "-m", "redundancy.cli", "study", "--quiet", "--out", out]
        wall, _ = best_time(lambda: subprocess.run(command, check=True, capture_output=True), 3)
    rows.append(("redundancy study, defaults (wall, whole command, best of 3)", wall))
    width = max(len(label) for label, _ in rows)
    print(f"{'what':<{width}}  {'measured':>9}  share of the command  share of {TARGET:g} s")
    for label, value in rows:
        print(f"{label:<{width}}  {value:>7.3f} s  {value / wall:>20.2f}  {value / TARGET:>14.2f}")


if __name__ == "__main__":
    main()
