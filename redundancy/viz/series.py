"""Time series out: every motion a study or a cycle run reports, one CSV file per motion, for
whoever programs the machine's controller (`Trajectory.to_frame`: t, q, x, ẋ, ẍ, F and, with a
circuit, each cylinder's load pressure and flow and the pump's flow and power, every column
named with its unit). Numbers are written in full (17 significant digits), so a file reads back
to the arrays it came from.

Names: ``motion_<objective>_<segment>.csv`` for a segment's improved start,
``motion_cycle_<strategy>.csv`` for a strategy's first whole cycle.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

from redundancy.planning.integrate import Trajectory
from redundancy.study.cycles import CycleStudy
from redundancy.study.output import write_atomically
from redundancy.study.study import Study


def write_series(study: Study | CycleStudy, folder: Path) -> list[Path]:
    """The CSV file of every motion ``study`` reports (a cycle run's alone, or a study's and
    its cycle section's) in ``folder``; return their paths."""
    motions: dict[str, Trajectory] = {}
    cycle = study if isinstance(study, CycleStudy) else study.cycle_study
    if isinstance(study, Study):
        for (objective, segment), motion in study.best_motions.items():
            motions[f"motion_{objective}_{segment}.csv"] = motion
    if cycle is not None:
        for strategy, motion in cycle.firsts.items():
            motions[f"motion_cycle_{strategy}.csv"] = motion
    for name, motion in motions.items():
        write_atomically(folder / name, partial(motion.to_frame().to_csv, index=False))
    return [folder / name for name in motions]
