"""Convergence under refinement: an optimum solved on ever finer grids has converged when the
last refinement moved it by less than `CONVERGED` (relative) and the finest grid's solve
succeeded. The bound (`redundancy.planning.bound`), the periodic optimum
(`redundancy.planning.cycles`) and the energy bound (`redundancy.planning.energy_bound`) are
judged by this one rule.
"""

from __future__ import annotations

CONVERGED = 0.005  # a last refinement that moves the optimum by less than this has converged


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
