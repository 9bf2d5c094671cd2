"""Closed forms of the slewing 3R arm of the tests (tests/data/slewing3r): links of 1.0, 0.8 and
0.5 m in the horizontal plane, each joint driven directly (x = q)."""

import numpy as np

from redundancy.model.values import modulo_turn

LINKS = (1.0, 0.8, 0.5)  # m


def start_configuration(v: float, elbow: int, point: np.ndarray) -> np.ndarray | None:
    """The configuration (3,) that puts the tool at ``point`` (2,) m with x3 = v on the
    ``elbow`` (±1) branch, or None where none does: links 2 and 3 as one rigid
    w = (0.8 + 0.5 cos v, 0.5 sin v) m, the triangle base-elbow-tool of sides 1 m, |w| and
    D = |point| gives the base angle q1 = atan2(point) ± arccos((1 + D² − |w|²) / 2D) by the
    law of cosines, and q2 closes it."""
    first, second, third = LINKS
    w = np.array([second + third * np.cos(v), third * np.sin(v)])
    reach = float(np.hypot(*point))
    cosine = (first**2 + reach**2 - w @ w) / (2 * first * reach)
    if abs(cosine) > 1:
        return None
    q1 = np.arctan2(point[1], point[0]) + elbow * np.arccos(cosine)
    r = np.asarray(point) - first * np.array([np.cos(q1), np.sin(q1)])  # elbow to tool
    q2 = modulo_turn(np.arctan2(r[1], r[0]) - q1 - np.arctan2(w[1], w[0]))
    return np.array([q1, q2, v])


def slew_held_configuration(v: float, elbow: int, point: np.ndarray) -> np.ndarray | None:
    """The configuration (3,) that puts the tool at ``point`` (2,) m with the slew x1 = v on the
    ``elbow`` (±1: the sign of q3) branch, or None where none does: the elbow at
    e = (cos v, sin v) m, links 2 and 3 reach r = point − e, |r| = d, so by the law of cosines
    q3 = ±(π − arccos((0.8² + 0.5² − d²) / (2 · 0.8 · 0.5))), and q2 turns
    w = (0.8 + 0.5 cos q3, 0.5 sin q3) onto r."""
    first, second, third = LINKS
    r = np.asarray(point) - first * np.array([np.cos(v), np.sin(v)])
    cosine = (second**2 + third**2 - r @ r) / (2 * second * third)
    if abs(cosine) > 1:
        return None
    q3 = elbow * (np.pi - np.arccos(cosine))
    w = np.array([second + third * np.cos(q3), third * np.sin(q3)])
    q2 = modulo_turn(np.arctan2(r[1], r[0]) - v - np.arctan2(w[1], w[0]))
    return np.array([v, q2, q3])


def shoulder_held_configuration(v: float, elbow: int, point: np.ndarray) -> np.ndarray | None:
    """The configuration (3,) that puts the tool at ``point`` (2,) m with x2 = v on the
    ``elbow`` (±1) branch, or None where none does: links 1 and 2 as one rigid
    u = (1 + 0.8 cos v, 0.8 sin v) m put the wrist at distance |u| from the base and 0.5 m
    from the point, D = |point| away, so by the law of cosines its angle is
    atan2(point) ± arccos((|u|² + D² − 0.5²) / 2 |u| D); q1 turns u onto it and q3 closes the
    last link onto the point."""
    first, second, third = LINKS
    u = np.array([first + second * np.cos(v), second * np.sin(v)])
    reach = float(np.hypot(*point))
    cosine = (u @ u + reach**2 - third**2) / (2 * np.sqrt(u @ u) * reach)
    if abs(cosine) > 1:
        return None
    wrist = np.arctan2(point[1], point[0]) + elbow * np.arccos(cosine)
    q1 = wrist - np.arctan2(u[1], u[0])
    r = np.asarray(point) - np.sqrt(u @ u) * np.array([np.cos(wrist), np.sin(wrist)])
    return np.array([q1, v, modulo_turn(np.arctan2(r[1], r[0]) - q1 - v)])
