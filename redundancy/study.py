"""The paper's study: every segment of a work cycle, each objective's improved initial
configuration, and the strategies it is compared with, as one report.

For each segment the comparison holds, with both peaks and whether every limit held:
- the unweighted and the M_H-weighted pseudoinverse from the default start (the held actuator at
  mid-stroke, or the reachable value nearest it: `default_start`);
- gradient projection with actuator-limit avoidance from the same start (the paper's baseline);
- the improved method for each objective (the best feasible start of its sweep).
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from redundancy.errors import InvalidInputError
from redundancy.initial_configuration import (
    SearchResult,
    StrategyRun,
    default_start,
    fixed_start_run,
    held_actuators,
    improved_start,
    scalar_or_list,
)
from redundancy.objectives import ENERGY, VELOCITY, Objective
from redundancy.resolvers import GradientProjection, Resolver
from redundancy.robot import Robot
from redundancy.simulate import TIME_STEP, time_grid
from redundancy.tasks import WorkCycle

BASELINES: tuple[tuple[str, Resolver], ...] = (
    ("unweighted, default start", VELOCITY.resolver),
    ("M_H-weighted, default start", ENERGY.resolver),
    ("gradient projection, default start", GradientProjection()),
)


@dataclass(frozen=True)
class Study:
    """Searches per objective and segment, and the strategy comparison."""

    robot: Robot
    cycle: WorkCycle
    held: tuple[str, ...]
    samples: int
    checked: tuple[str, ...]
    searches: dict[str, tuple[SearchResult, ...]]
    runs: tuple[StrategyRun, ...]

    def search(self, objective: str, segment: str) -> SearchResult:
        for result in self.searches[objective]:
            if result.segment.name == segment:
                return result
        raise InvalidInputError(f"no search of {objective!r} on segment {segment!r}")

    def report(self) -> dict:
        """The study as JSON-ready data."""
        return {
            "robot": self.robot.name,
            "payload": self.robot.payload,
            "task": self.cycle.name,
            "samples": self.samples,
            "checked_actuators": list(self.checked),
            "studies": [
                {
                    "objective": name,
                    "measure": searches[0].objective.label if searches else None,
                    "segments": [_search_report(s) for s in searches],
                }
                for name, searches in self.searches.items()
            ],
            "comparison": [run.summary() for run in self.runs],
        }

    def table(self) -> str:
        """The comparison as a fixed-width text table."""
        start = "start " + ",".join(self.held)
        width = max(10, len(start) + 1, 8 * len(self.held) + 1)
        names = max(8, *(len(s.name) + 2 for s in self.cycle.segments))
        header = (
            f"{'segment':<{names}}{'strategy':<36}{start:>{width}}"
            f"{'peak ẋᵀẋ':>12}{'peak ẋᵀM_Hẋ':>13}  limits"
        )
        lines = [header, "-" * len(header)]
        for run in self.runs:
            row = run.summary()
            held = "held" if row["within_limits"] else "VIOLATED"
            values = ",".join(f"{v:.3f}" for v in run.start)
            lines.append(
                f"{run.segment:<{names}}{run.strategy:<36}{values:>{width}}"
                f"{row['peak_velocity_norm']:>12.5f}{row['peak_kinetic']:>13.3f}  {held}"
            )
        for name, searches in self.searches.items():
            for search in searches:
                if search.best is None:
                    closest = search.closest_violation
                    lines.append(
                        f"note: {name} objective, segment {search.segment.name}: no sampled "
                        f"start stays inside the limits"
                        + (f"; closest: {closest}" if closest else "")
                    )
        return "\n".join(lines)


def _search_report(search: SearchResult) -> dict:
    best = search.best
    closest = search.closest_violation if best is None else None
    box = search.feasible_box
    return {
        "name": search.segment.name,
        "start": search.segment.start.tolist(),
        "end": search.segment.end.tolist(),
        "held_actuator": search.held[0] if len(search.held) == 1 else list(search.held),
        "feasible_range": None if box is None else (box[0] if len(box) == 1 else box).tolist(),
        "best": None if best is None else {"value": scalar_or_list(best.values), "peak": best.peak},
        "closest_violation": None if closest is None else str(closest),
        "samples": [
            {
                "value": scalar_or_list(s.values),
                "peak": s.peak,
                "feasible": s.feasible,
                "reason": s.reason,
            }
            for s in search.samples
        ],
    }


def run_study(
    robot: Robot,
    cycle: WorkCycle,
    objectives: tuple[Objective, ...] = (VELOCITY, ENERGY),
    samples: int = 100,
    checked: tuple[str, ...] | None = None,
    time_step: float = TIME_STEP,
    progress: bool = True,
) -> Study:
    """Run every objective's improved search and the comparison strategies on every segment.

    The held actuators are the task's ``held`` or, if it names none, the last n − m actuators
    (`held_actuators`).
    """
    from tqdm import tqdm

    held = held_actuators(robot, cycle)
    steps = sum(len(time_grid(s, time_step)) - 1 for s in cycle.segments)
    total = steps * (len(objectives) + len(BASELINES))
    bar = tqdm(total=total, unit="step", desc="study", disable=not progress, mininterval=0.5)
    with bar:
        searches: dict[str, tuple[SearchResult, ...]] = {}
        runs: list[StrategyRun] = []
        for segment in cycle.segments:
            start = default_start(robot, segment, held)
            for name, resolver in BASELINES:
                bar.set_description(f"{segment.name}: {name}")
                runs.append(
                    fixed_start_run(
                        robot, resolver, name, segment, held, start, checked, time_step, bar.update
                    )
                )
        for objective in objectives:
            found = []
            for segment in cycle.segments:
                bar.set_description(f"{segment.name}: improved, {objective.name}")
                search = improved_start(
                    robot, segment, objective, held, samples, checked, time_step, bar.update
                )
                found.append(search)
                best = search.best
                if best is not None:
                    runs.append(
                        StrategyRun(
                            segment.name,
                            f"improved, {objective.name} objective",
                            best.values,
                            search.motion(best),
                        )
                    )
            searches[objective.name] = tuple(found)
    order = {s.name: i for i, s in enumerate(cycle.segments)}
    runs.sort(key=lambda r: order[r.segment])
    return Study(
        robot,
        cycle,
        held,
        samples,
        tuple(robot.actuators.names if checked is None else checked),
        searches,
        tuple(runs),
    )


def write_atomically(path: Path, write) -> None:
    """Call ``write(temporary_path)``, then move the result over ``path`` in one step, so a
    failure never leaves ``path`` half-written or loses what it held."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix
    )
    os.close(handle)
    try:
        write(Path(temporary))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # mkstemp makes it private; give a normal file's mode
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_report(study: Study, path: Path) -> None:
    """The study's JSON report, written atomically."""
    text = json.dumps(study.report(), indent=1, allow_nan=False)
    write_atomically(path, lambda p: p.write_text(text + "\n"))
