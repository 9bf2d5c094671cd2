"""Convergence under refinement: an optimum solved on ever finer grids has converged when the
last refinement moved it by less than `CONVERGED` (relative) and the finest grid's solve
succeeded. The bound (`redundancy.planning.bound`), the periodic optimum
(`redundancy.planning.cycles`) and the energy bound (`redundancy.planning.integral_optimum`) are
judged by this one rule.
"""

from __future__ import annotations

import itertools

from redundancy.errors import InvalidInputError
from redundancy.model.values import is_whole

CONVERGED = 0.005  # a last refinement that moves the optimum by less than this has converged
MOST_INTERVALS = 1000  # of a grid given by hand: the solvers' cost grows with it, steeply


def checked_grids(grids: object, least: int) -> tuple[int, ...]:
    """``grids``, interval counts of ever finer grids, as a tuple: whole numbers within [least,
    `MOST_INTERVALS`], strictly increasing; otherwise `InvalidInputError` naming them."""
    given = tuple(grids) if isinstance(grids, list | tuple) else ()
    if (
        not given
        or not all(is_whole(g, least, MOST_INTERVALS) for g in given)
        or any(b <= a for a, b in itertools.pairwise(given))
    ):
        raise InvalidInputError(
            f"grids must be strictly increasing whole interval counts within [{least}, "
            f"{MOST_INTERVALS:,}]; got {grids!r}"
        )
    return tuple(int(g) for g in given)


class Refined:
    """An optimum found on a sequence of ever finer ``grids``, coarsest first; each grid has
    its ``optimum`` and whether its solve succeeded (``success``)."""

    grids: tuple

    @property
    def optimum(self) -> float:
        """The optimum on the finest grid."""
        return self.grids[-1].optimum

    @property
    def change(self) -> float | None:
        """|optimum on the finest grid − on the one before| / |on the finest|, or None with one
        grid or a zero optimum."""
        if len(self.grids) < 2 or self.grids[-1].optimum == 0:
            return None
        finest, before = self.grids[-1].optimum, self.grids[-2].optimum
        return abs(finest - before) / abs(finest)

    @property
    def converged(self) -> bool:
        """The finest grid's solve succeeded and refining the grid last moved the optimum by
        less than `CONVERGED`."""
        change = self.change
        return bool(self.grids[-1].success) and change is not None and change < CONVERGED

    @property
    def failure(self) -> str | None:
        """Why the optimum is no result, in one line (None where it converged): the solver's
        own message where the finest grid's solve failed, else how much the last refinement
        moved it."""
        finest, change = self.grids[-1], self.change
        if not finest.success:
            return (
                f"NOT converged: the solver failed on the grid of {finest.intervals} intervals "
                f"({finest.message})"
            )
        if self.converged:
            return None
        return f"NOT converged, change {'-' if change is None else f'{100 * change:.2f} %'}"
