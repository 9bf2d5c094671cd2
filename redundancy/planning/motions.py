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
from redundancy.model.robot import Robot
from redundancy.planning.integrate import TIME_STEP, Trajectory, simulate
from redundancy.planning.tasks import Chain, Segment
from redundancy.resolution.laws import Resolver

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
    if isinstance(path, Segment):
        (law,) = per_segment(Chain(path.name, (path,)), laws)
        return simulate(robot, law, path, starts, time_step, **options)
    q = robot.configuration(starts, "starts")
    pieces = []
    for segment, law in zip(path.segments, per_segment(path, laws)):
        pieces.append(simulate(robot, law, segment, q, time_step, **options))
        q = pieces[-1].q[:, -1]
    return joined(path, pieces)


def per_segment(path: Chain, laws: Laws) -> tuple[Resolver, ...]:
    """One law per segment of ``path``: ``laws`` itself, or one law repeated."""
    if isinstance(laws, Resolver):
        return (laws,) * len(path.segments)
    laws = tuple(laws)
    if len(laws) != len(path.segments):
        raise InvalidInputError(
            f"{len(laws)} laws for the {len(path.segments)} segments of {path.name!r}"
        )
    return laws


SAMPLED = ("t", "q", "x", "x_dot", "y", "measure")  # a motion's arrays over its samples


def joined(path: Chain, pieces: Sequence[Trajectory]) -> Trajectory:
    """k motions along each segment of ``path`` in turn (each piece starting where the one
    before ended) as k motions along the whole chain: times from the chain's start, each later
    piece's first sample left out (it repeats the corner the one before ended at), each motion
    padded by repeating its last sample. A motion failed or stopped where any piece did."""
    names = SAMPLED if all(p.measure is not None for p in pieces) else SAMPLED[:-1]
    columns: dict[str, list[np.ndarray]] = {name: [] for name in names}
    for i in range(len(pieces[0])):
        parts: dict[str, list[np.ndarray]] = {name: [] for name in names}
        for number, (offset, piece) in enumerate(zip(path.offsets, pieces)):
            times = piece.t[i]
            kept = slice(0 if number == 0 else 1, int(np.searchsorted(times, times[-1])) + 1)
            for name in names:
                values = getattr(piece, name)[i, kept]
                parts[name].append(values + offset if name == "t" else values)
        for name in names:
            columns[name].append(np.concatenate(parts[name]))
    t, q, x, x_dot, y = (padded(columns[name]) for name in SAMPLED[:-1])
    measure = padded(columns["measure"]) if "measure" in columns else None
    first = pieces[0]
    return Trajectory(
        first.robot,
        path,  # type: ignore[arg-type]
        first.resolver,
        t,
        q,
        x,
        x_dot,
        y,
        np.any([p.failed for p in pieces], axis=0),
        first.checked,
        np.any([p.stopped for p in pieces], axis=0),
        first.objective,
        measure,
        first.sparse,
        first.allowance,
        first.circuit,
    )


def padded(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """Arrays (T_i, ...) as one (k, max T_i, ...), each padded by repeating its last row."""
    length = max(len(a) for a in arrays)
    return np.stack([np.concatenate([a, np.repeat(a[-1:], length - len(a), 0)]) for a in arrays])


def concatenated(first: Trajectory, second: Trajectory) -> Trajectory:
    """Two batches of motions on one path as one, padded to the longer by repetition."""

    t, q, x, x_dot, y = (padded([*getattr(first, n), *getattr(second, n)]) for n in SAMPLED[:-1])
    measure = None
    if first.measure is not None and second.measure is not None:
        measure = padded([*first.measure, *second.measure])
    return Trajectory(
        first.robot,
        first.segment,
        first.resolver,
        t,
        q,
        x,
        x_dot,
        y,
        np.concatenate([first.failed, second.failed]),
        first.checked,
        np.concatenate([first.stopped, second.stopped]),
        first.objective,
        measure,
        first.sparse,
        first.allowance,
        first.circuit,
        None
        if first.steps is None or second.steps is None
        else first.steps.joined(second.steps, len(first)),
    )
