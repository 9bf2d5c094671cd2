"""States through the one Pinocchio pass against the distinct states, and the CPU time, of what
`redundancy study` computes: the study of the paper's segments, every run's figures, the figures
and playbacks, and the cycle section, here in one process so that every pass is counted. The
command makes the improved searches first and computes the cycle section, whose per-segment plan
reads the first objective's searches, in a second process, so its ratio is printed apart too.

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
from redundancy.study.study import STUDY_CYCLES, cycle_section, run_study, study_searches
from redundancy.viz.playback import write_playbacks
from redundancy.viz.plots import write_figures


def main() -> None:
    robot = load_robot("hiab031")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    start = time.process_time()
    with counting() as study_counts, tempfile.TemporaryDirectory() as folder:
        searches = study_searches(robot, cycle, (VELOCITY, ENERGY))
        study = run_study(
            robot, cycle, (VELOCITY, ENERGY), progress=False, cycles=0, searches=searches
        )
        write_figures(study, Path(folder))
        write_playbacks(study, Path(folder))
        for run in study.runs:
            run.summary()
    with counting() as cycle_counts:  # the command computes it in a second process
        cycle_section(robot, cycle, VELOCITY, STUDY_CYCLES, segments=searches.first())
    cpu = time.process_time() - start
    both = study_counts.evaluated + cycle_counts.evaluated
    for name, counts in (("the study", study_counts), ("its cycle section", cycle_counts)):
        print(
            f"{name}: {counts.evaluated:,} states evaluated, {counts.distinct:,} distinct, "
            f"ratio {counts.ratio:.3f}; passed again at their velocities: {counts.moving:,}"
        )
    distinct = len(study_counts.seen | cycle_counts.seen)
    print(f"states evaluated: {both:,}; distinct: {distinct:,}")
    print(f"evaluated / distinct: {both / distinct:.3f} (target ≤ 1.05)")
    again = study_counts.moving + cycle_counts.moving
    print(f"with the velocity passes: {(both + again) / distinct:.3f}")
    print(f"CPU time in this process: {cpu:.1f} s")


if __name__ == "__main__":
    main()
