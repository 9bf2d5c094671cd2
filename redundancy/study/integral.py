"""An integral objective three ways, side by side: the objective's law from the documented
default start (for the velocity objective of directly driven joints, the local pseudoinverse of
least q̇ᵀq̇), the improved start (the search of the held actuators' start under the same
objective) and the optimum by dynamic programming over the held actuators' histories
(`redundancy.planning.integral_optimum`), the global optimum over its grid. Result data only;
docs/integral.md shows the table.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from redundancy.model.robot import Robot
from redundancy.planning.integral_optimum import GRIDS, IntegralOptimum, integral_optimum
from redundancy.planning.integrate import simulate
from redundancy.planning.starts import SearchResult, default_start, improved_start
from redundancy.planning.tasks import Segment
from redundancy.resolution.objectives import Objective
from redundancy.resolution.objectives import objective as named
from redundancy.resolution.state import evaluate


@dataclass(frozen=True)
class Figures:
    """A strategy's figures: the objective's ``integral`` and ``peak`` (its measure's unit
    times s, and its unit), and the largest actuator speed |ẋ| and acceleration |ẍ| (m/s and
    m/s², rad/s and rad/s² for a rotary actuator)."""

    strategy: str
    integral: float
    peak: float
    speed: float
    acceleration: float


@dataclass(frozen=True)
class Comparison:
    """The local law, the improved start and the optimum by dynamic programming (``figures``,
    in that order), the improved start's search and the optimum itself (its grids, its
    convergence)."""

    objective: Objective
    figures: tuple[Figures, ...]
    search: SearchResult
    optimum: IntegralOptimum


def compare(
    robot: Robot,
    segment: Segment,
    objective: str | Objective,
    held: str | Sequence[str],
    speeds=None,
    accelerations=None,
    grids: tuple[int, ...] = GRIDS,
) -> Comparison:
    """``objective`` (an integral one) along ``segment`` by the three strategies of the module
    docstring. ``speeds`` and ``accelerations`` bind the optimum (see `integral_optimum`); the
    local motions are reported with what they reach."""
    objective = named(objective)
    start = default_start(robot, segment, held)[1][None]
    search = improved_start(robot, segment, objective, held)
    motions = {
        "local law, default start": simulate(robot, objective.resolver, segment, start),
        "improved start": search.best_motion,
    }
    figures = [
        Figures(
            name,
            float(motion.score(objective)[0]),
            float(motion.values(objective)[0].max()),
            float(np.abs(motion.x_dot[0]).max()),
            float(np.abs(motion.x_ddot[0]).max()),
        )
        for name, motion in motions.items()
    ]
    optimum = integral_optimum(
        robot, segment, objective, held, grids=grids, speeds=speeds, accelerations=accelerations
    )
    h = optimum.t[1]
    x_dot = np.gradient(optimum.x, h, axis=0)  # at the nodes; the transitions' own below
    steps = np.diff(optimum.x, axis=0) / h
    figures.append(
        Figures(
            "global optimum",
            optimum.optimum,
            float(objective.measure(evaluate(robot, optimum.q), x_dot).max()),
            float(np.abs(steps).max()),
            float(np.abs(np.diff(steps, axis=0)).max() / h),
        )
    )
    return Comparison(objective, tuple(figures), search, optimum)
