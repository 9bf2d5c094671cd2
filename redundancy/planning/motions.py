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
from dataclasses import replace

import numpy as np

from redundancy.errors import InvalidInputError
from redundancy.model.robot import Robot
from redundancy.planning.integrate import TIME_STEP, Trajectory, simulate
from redundancy.planning.tasks import Chain, Segment
from redundancy.resolution.laws import Resolver
from redundancy.resolution.state import ActuatorSpace

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


def joined(path: Chain, pieces: Sequence[Trajectory]) -> Trajectory:
    """k motions along each segment of ``path`` in turn (each piece starting where the one
    before ended) as k motions along the whole chain: times from the chain's start, each later
    piece's first sample left out (it repeats the corner the one before ended at), each motion
    padded by repeating its last sample. A motion failed or stopped where any piece did."""
    firsts = np.cumsum([0, *(p.t.size for p in pieces)])
    index = []  # each motion's samples among the pieces' flattened motion by motion
    for i in range(len(pieces[0])):
        parts = []
        for number, (first, piece) in enumerate(zip(firsts, pieces)):
            times = piece.t[i]
            count = int(np.searchsorted(times, times[-1])) + 1
            parts.append(first + i * times.size + np.arange(min(number, 1), count))
        index.append(np.concatenate(parts))
    return _gathered(
        path,
        pieces,
        padded(index),
        path.offsets,
        failed=np.any([p.failed for p in pieces], axis=0),
        stopped=np.any([p.stopped for p in pieces], axis=0),
        steps=None,
    )


def padded(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """Arrays (T_i, ...) as one (k, max T_i, ...), each padded by repeating its last row."""
    length = max(len(a) for a in arrays)
    return np.stack([np.concatenate([a, np.repeat(a[-1:], length - len(a), 0)]) for a in arrays])


def concatenated(first: Trajectory, second: Trajectory) -> Trajectory:
    """Two batches of motions on one path as one, padded to the longer by repetition."""
    rows = [
        offset + i * part.t.shape[1] + np.arange(part.t.shape[1])
        for offset, part in ((0, first), (first.t.size, second))
        for i in range(len(part))
    ]
    return _gathered(
        first.segment,
        (first, second),
        padded(rows),
        (0.0, 0.0),
        failed=np.concatenate([first.failed, second.failed]),
        stopped=np.concatenate([first.stopped, second.stopped]),
        steps=None
        if first.steps is None or second.steps is None
        else first.steps.joined(second.steps, len(first)),
    )


def _gathered(path, pieces: Sequence[Trajectory], index: np.ndarray, shifts, **fields):
    """The samples ``index`` (k, T) among the ``pieces``' samples flattened motion by motion
    (each piece's times shifted by its ``shifts``, s) as k motions along ``path``; the other
    ``fields`` given."""

    def gather(name: str) -> np.ndarray:
        arrays = [getattr(p, name) for p in pieces]
        return np.concatenate([a.reshape(-1, *a.shape[2:]) for a in arrays])[index]

    t = np.concatenate([p.t.ravel() + shift for p, shift in zip(pieces, shifts)])[index]
    measure = gather("measure") if all(p.measure is not None for p in pieces) else None
    spaces = [p.space for p in pieces]
    space = None
    if all(s is not None for s in spaces):
        space = ActuatorSpace.joined(spaces).take(index.ravel())  # type: ignore[arg-type]
    return replace(
        pieces[0],
        segment=path,
        t=t,
        q=gather("q"),
        x=gather("x"),
        x_dot=gather("x_dot"),
        y=gather("y"),
        measure=measure,
        space=space,
        **fields,
    )
