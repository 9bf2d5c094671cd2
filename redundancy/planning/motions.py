"""Motions along any path: a segment, or a chain of segments such as a work cycle.

A chain is integrated segment by segment, each from where the one before ended, and the pieces
are joined into one `Trajectory` along the chain. The integrator restarts at every corner
because ẏ may jump there (at the paper's constant speed it turns by 0.5 m/s): integrated across
a corner, the adaptive method's error control does not see the jump in time, and over the
crane's cycle its q departed by 2e-3 at tolerance 1e-6 (9e-7 at 1e-7 with the repetitions'
feedback), for twice to four times the steps.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.robot import Robot, require_robot
from redundancy.planning.integrate import TIME_STEP, Trajectory, chained, simulate
from redundancy.planning.tasks import Chain, Segment
from redundancy.resolution.laws import Resolver, require_resolver

Laws = Resolver | Sequence[Resolver]  # one law for every segment of a chain, or one per segment


def simulate_path(
    robot: Robot,
    laws: Laws,
    path: Segment | Chain,
    starts: np.ndarray,
    time_step: float = TIME_STEP,
    **options,
) -> Trajectory:
    """`simulate` along ``path`` from every start (k, n): a segment at once; a chain segment by
    segment, each from where the one before ended (q continuous at every corner), by ``laws``
    (one `Resolver`, or one per segment that reads its segment's time), joined along the
    chain's time. The other ``options`` as `simulate`'s."""
    require_robot(robot)
    if isinstance(path, Segment):
        (law,) = per_segment(Chain(path.name, (path,)), laws)
        return simulate(robot, law, path, starts, time_step, **options)
    q = robot.configuration(starts, "starts")
    pieces = []
    for segment, law in zip(path.segments, per_segment(path, laws)):
        pieces.append(simulate(robot, law, segment, q, time_step, **options))
        q = pieces[-1].q[:, -1]
    return chained(path, pieces)


def per_segment(path: Chain, laws: Laws) -> tuple[Resolver, ...]:
    """One law per segment of ``path``: ``laws`` itself, or one law repeated."""
    if isinstance(laws, Resolver):
        return (laws,) * len(path.segments)
    if isinstance(laws, str) or not isinstance(laws, Sequence):
        require_resolver(laws)  # neither one law nor a sequence of them: says what a law is
    laws = tuple(require_resolver(law) for law in laws)
    if len(laws) != len(path.segments):
        raise InvalidInputError(
            f"{len(laws)} laws for the {len(path.segments)} segments of {path.name!r}"
        )
    return laws
