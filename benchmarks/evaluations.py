"""States through the one Pinocchio pass against the distinct states, and the CPU time, of what
`redundancy study` computes: the study of the paper's segments, every run's figures, the figures
and playbacks, and the cycle section, here in one process so that every pass is counted.

Run: python benchmarks/evaluations.py
The target (issue 24): evaluated ≤ 1.05 × distinct. Printed, never asserted.
"""

import tempfile
import time
from pathlib import Path

from counting import counting  # the script's folder: the counting wrapper

from redundancy import load_robot
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.objectives import ENERGY, VELOCITY
from redundancy.study.study import STUDY_CYCLES, cycle_section, run_study
from redundancy.viz.playback import write_playbacks
from redundancy.viz.plots import write_figures


def main() -> None:
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    start = time.process_time()
    with counting() as counts, tempfile.TemporaryDirectory() as folder:
        study = run_study(robot, cycle, (VELOCITY, ENERGY), progress=False, cycles=0)
        write_figures(study, Path(folder))
        write_playbacks(study, Path(folder))
        for run in study.runs:
            run.summary()
        cycle_section(robot, cycle, VELOCITY, STUDY_CYCLES)
    cpu = time.process_time() - start
    print(f"states evaluated: {counts.evaluated:,}; distinct: {counts.distinct:,}")
    print(f"evaluated / distinct: {counts.ratio:.3f} (target ≤ 1.05)")
    print(f"CPU time in this process: {cpu:.1f} s")


if __name__ == "__main__":
    main()
