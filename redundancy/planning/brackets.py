"""Locating where a function of one variable changes sign, and its least value, from samples.

The fast improved search (`redundancy.planning.starts`) samples the margin μ(v) of a start v (its
least distance to a limit over the whole motion: continuous in v, so the ends of the feasible set
are its zeros) and the objective's peak. These helpers choose the next values to sample:
`grid_over` the first ones over pieces of the values, `bracket_probes` near each zero (μ may have
a kink at its zero, where the binding limit changes, and then a side's own line through its two
nearest values is the accurate fit), `edge_probes` towards the end of the values where μ is
defined at all, `summit_probes` around the highest μ while no sample is inside, `vertex_probes`
near the least peak and in any other basin of the peak that may hold a lower one, `end_probe`
beside the least where it lies at an end of the feasible set, and `new_probes` of those, the
ones not sampled already.
"""

from __future__ import annotations

import math

import numpy as np


def bracket_probes(values, margins, inside, tolerance) -> list[float]:
    """Probes for every bracket of ``inside`` (k,) (neighbours on either side of a zero of
    ``margins``) wider than ``tolerance``: the zeros, in the bracket, of the line through its
    ends, of the parabolas through its ends and either next value, and of each side's own line
    through its two nearest values, at 0.45 of a tolerance either side of each (so that a zero
    that close closes the bracket); and the bracket's midpoint where those zeros disagree by
    more than a quarter of it."""
    values, margins, inside = _floats(values), _floats(margins), np.asarray(inside).tolist()
    probes: list[float] = []
    usable = [math.isfinite(margin) for margin in margins]
    for i in range(len(values) - 1):
        a, b = values[i], values[i + 1]
        if inside[i] == inside[i + 1] or b - a <= tolerance:
            continue
        fits = [(i, i + 1), (i - 1, i + 1), (i, i + 2)]  # across the bracket
        sides = [j for j in (i - 1, i + 1) if 0 <= j < len(values) - 1]
        fits += [(j, j + 1) for j in sides if inside[j] == inside[j + 1]]  # each side's own
        zeros = []
        for first, last in fits:
            if first < 0 or last >= len(values) or not all(usable[first : last + 1]):
                continue
            u = [value - a for value in values[first : last + 1]]
            zeros += [
                a + z for z in interpolant_zeros(u, margins[first : last + 1]) if 0 < z < b - a
            ]
        if not zeros or max(zeros) - min(zeros) > (b - a) / 4:
            probes.append((a + b) / 2)
        for zero in clusters(sorted(zeros), tolerance):
            probes += [_clip(zero + tolerance * side, a, b) for side in (-0.45, 0.45)]
    return probes


def _floats(values) -> list[float]:
    """An array's values as Python floats: these helpers walk a few dozen samples one by one,
    which numpy's per-call cost would make ten times slower, alike to the last bit. The values
    are distinct, as a search's are (`grid_over`, `new_probes`): a fit through two equal ones
    divides by zero."""
    return np.asarray(values, dtype=float).tolist()


def _clip(value: float, low: float, high: float) -> float:
    """``value`` within [low, high], as numpy's clip."""
    return min(max(value, low), high)


def grid_over(pieces, count) -> np.ndarray:
    """``count`` values evenly along the intervals ``pieces`` (p, 2), in order, laid end to end
    (none spent on the gaps between them), the ends of every piece, the middle of each piece
    none of the ``count`` falls in, and the middle of every gap: the margin's brackets at a
    piece's ends are seen, a piece narrower than the spacing is sampled inside too, and no
    bracket, crossing or fit spans a gap."""
    lengths = pieces[:, 1] - pieces[:, 0]
    ends = np.cumsum(lengths)
    along = np.linspace(0.0, ends[-1], count)
    piece = np.minimum(np.searchsorted(ends, along), len(pieces) - 1)
    grid = np.clip(pieces[piece, 0] + along - (ends - lengths)[piece], *pieces[piece].T)
    missed = [(a + b) / 2 for a, b in pieces if not ((grid >= a) & (grid <= b)).any()]
    gaps = (pieces[1:, 0] + pieces[:-1, 1]) / 2
    return np.unique(np.concatenate([grid, pieces.ravel(), missed, gaps]))


EDGE_PARTS = 5  # parts edge_probes divide an interval beside the end of a branch into


def edge_probes(values, margins, tolerance) -> list[float]:
    """Probes dividing into `EDGE_PARTS` each interval wider than ``tolerance`` between a value
    whose margin is finite and below 0 and a neighbour where it is not defined (−inf: past the
    end of a branch of inverse-kinematics solutions, no configuration there). Such a branch
    ends at a fold, where its configuration changes as the square root of the distance s to
    the end: a margin μ₀ + c √s + d s may fall between the samples and still turn up through 0
    close to the end, so no slope seen bounds it. Each round divides the interval beside the
    end again, locating the end; a zero of the margin found beside it is then a reachable
    bracket's (`bracket_probes`)."""
    defined = np.isfinite(margins)
    probes: list[float] = []
    for i in np.flatnonzero(defined[:-1] != defined[1:]):
        a, b = values[i], values[i + 1]
        if b - a > tolerance and margins[i if defined[i] else i + 1] < 0:
            probes += list(a + (b - a) * np.arange(1, EDGE_PARTS) / EDGE_PARTS)
    return probes


def interpolant_zeros(u: list[float], m: list[float]) -> list[float]:
    """The real zeros of the polynomial through two or three points (u_i, m_i), distinct u_i:
    in Newton's form p(u) = m_0 + d_1 (u − u_0) + d_2 (u − u_0)(u − u_1), with the divided
    differences d_1 = (m_1 − m_0) / (u_1 − u_0) and d_2 = ((m_2 − m_1) / (u_2 − u_1) − d_1) /
    (u_2 − u_0), that is c_2 u² + c_1 u + c_0; a parabola's zeros by the quadratic formula
    without cancellation, s = −(c_1 + sign(c_1) √(c_1² − 4 c_2 c_0)) / 2, u = s / c_2 and
    c_0 / s."""
    d1 = (m[1] - m[0]) / (u[1] - u[0])
    d2 = 0.0 if len(u) == 2 else ((m[2] - m[1]) / (u[2] - u[1]) - d1) / (u[2] - u[0])
    c2, c1, c0 = d2, d1 - d2 * (u[0] + u[1]), m[0] - d1 * u[0] + d2 * u[0] * u[1]
    if c2 == 0:
        return [] if c1 == 0 else [-c0 / c1]
    discriminant = c1 * c1 - 4 * c2 * c0
    if discriminant < 0:
        return []
    s = -(c1 + math.copysign(math.sqrt(discriminant), c1)) / 2
    return [s / c2, c0 / s] if s else [0.0]


def clusters(values: list[float], tolerance: float) -> list[float]:
    """The means of runs of sorted ``values`` less than ``tolerance`` apart."""
    breaks = np.flatnonzero(np.diff(values) >= tolerance) + 1
    return [float(run.mean()) for run in np.split(np.array(values), breaks)] if values else []


def new_probes(probes: list[float], values: np.ndarray, tolerance: float) -> np.ndarray:
    """The probes, sorted, without those within a tenth of ``tolerance`` of a known value or
    of a smaller probe."""
    kept: list[float] = []
    for probe in sorted(probes):
        if np.abs(values - probe).min() > tolerance / 10 and (
            not kept or probe - kept[-1] > tolerance / 10
        ):
            kept.append(probe)
    return np.array(kept)


GOLDEN = (3 - math.sqrt(5)) / 2  # the golden section's share of an interval, 0.382
SUMMIT_SLOPE = 2.0  # how much steeper than the samples show the margin may rise between them


def summit_probes(values, margins, tolerance) -> list[float]:
    """The midpoints between the value of the highest finite margin and each neighbour more than
    ``tolerance`` from it: where no sample is inside, the continuous margin's highest point
    lies between those neighbours, and each round halves the interval around it. None where
    the margin cannot reach 0 there rising at `SUMMIT_SLOPE` times the steepest slope the
    samples show: a summit that far below is the motions' own, not a narrow feasible set
    between samples."""
    finite = np.isfinite(margins)
    if not finite.any():
        return []
    best = int(np.argmax(np.where(finite, margins, -np.inf)))
    neighbours = [j for j in (best - 1, best + 1) if 0 <= j < len(values)]
    pairs = np.flatnonzero(finite[:-1] & finite[1:])  # neighbours whose margins are known
    slopes = np.abs((margins[pairs + 1] - margins[pairs]) / (values[pairs + 1] - values[pairs]))
    steepest = SUMMIT_SLOPE * slopes.max() if slopes.size else np.inf
    rise = steepest * max(abs(values[j] - values[best]) for j in neighbours) if neighbours else 0
    if margins[best] + rise < 0:
        return []
    return [
        (values[best] + values[j]) / 2
        for j in neighbours
        if abs(values[j] - values[best]) > tolerance
    ]


def vertex_probes(values, peaks, tolerance) -> list[float]:
    """Probes of the least peak's basin and of every other basin that may hold a lower one.

    Around the least finite peak, and around every other local minimum of the peaks whose
    parabola dips below that least peak (a second basin of the peak over the values, sampled
    above the first's least sample by the grid, may hold the least of all): the vertex of the
    parabola through it and its two neighbours, when both are finite and they span more than
    twice ``tolerance``. The parabola p(v) = p₁ + d (v − v₁) + a (v − v₁)², a the second
    divided difference, dips to p₁ − d² / 4a at its vertex v₁ − d / 2a."""
    least = int(np.argmin(peaks))
    values, peaks = _floats(values), _floats(peaks)
    probes = []
    for i in range(1, len(values) - 1):
        v, p = values[i - 1 : i + 2], peaks[i - 1 : i + 2]
        if not all(map(math.isfinite, p)) or v[2] - v[0] <= 2 * tolerance:
            continue
        slope, curvature = _parabola(v, p)
        if i != least and not (  # a local minimum: its curvature is > 0
            p[1] < p[0]
            and p[1] < p[2]
            and curvature > 0
            and p[1] - slope**2 / (4 * curvature) < peaks[least]
        ):
            continue
        if curvature:
            probes += _vertex_probe(v, v[1] - slope / (2 * curvature), tolerance)
    return probes


def _parabola(v, p) -> tuple[float, float]:
    """The slope d at the middle value v₁ and the curvature a (the second divided difference)
    of the parabola through (v, p) (3,) each, in order of v."""
    slopes = [(p[1] - p[0]) / (v[1] - v[0]), (p[2] - p[1]) / (v[2] - v[1])]
    curvature = (slopes[1] - slopes[0]) / (v[2] - v[0])
    return slopes[0] + curvature * (v[1] - v[0]), curvature


def _vertex_probe(v, vertex, tolerance) -> list[float]:
    """The ``vertex`` of a parabola through three values v (3,), kept ``tolerance`` / 2 inside
    their span; where it creeps (within an eighth of the wider side from the middle value, as
    at a kink of the peak), the golden section of that side."""
    wider = 0 if v[1] - v[0] > v[2] - v[1] else 2
    if abs(vertex - v[1]) < abs(v[wider] - v[1]) / 8:  # creeping: a kink, not a parabola
        vertex = v[1] + GOLDEN * (v[wider] - v[1])
    return [_clip(vertex, v[0] + tolerance / 2, v[2] - tolerance / 2)]


def end_probe(values, peaks, spacing) -> list[float]:
    """The midpoint between the least finite peak and its one finite neighbour, where the
    other side has none (the least peak at an end of the feasible set) and that neighbour is
    farther than a quarter of ``spacing``: the peak may dip between them, where
    `vertex_probes`, which need a neighbour on either side, do not look (a peak's least is
    often a kink, where the motion's peak moves from one instant to another, and no parabola
    through one side foresees it). Once that side is sampled at a quarter of the spacing, no
    more: a dip narrower stays unseen (a heuristic, as any sampling of a peak)."""
    best = int(np.argmin(peaks))
    sides = [j for j in (best - 1, best + 1) if 0 <= j < len(values) and np.isfinite(peaks[j])]
    if not np.isfinite(peaks[best]) or len(sides) != 1:
        return []
    j = sides[0]
    if abs(values[j] - values[best]) <= spacing / 4 * (1 + 1e-9):
        return []
    return [(values[best] + values[j]) / 2]
