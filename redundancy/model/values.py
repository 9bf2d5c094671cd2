"""Numbers as files, options and the API give them: what they are, and the toolkit's bounds.

The files themselves are checked by their models (`redundancy.model.schema`).
"""

from __future__ import annotations

import math

import numpy as np

MAX_PAYLOAD = 1e5  # kg: beyond any hydraulic machine this toolkit models
MAX_LINK_MASS = 1e6  # kg: a link of a URDF; a mining shovel's boom is about a tenth of it
MAX_INERTIA = 1e8  # kg·m²: an inertia entry of a URDF link; such a boom's is about a tenth
MAX_SPEED = 10.0  # m/s along a task path: beyond any hydraulic manipulator's tool
MAX_ACCELERATION = 100.0  # m/s² along a task path: beyond any hydraulic manipulator's tool


def decimal(text: str) -> float:
    """The number ``text`` writes, in the notation files and options use (``-1.5``, ``2e-3``,
    ``inf``, ``nan``); `ValueError` for anything else, Python's ``1_000`` included."""
    if "_" in text:
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def modulo_turn(angle: np.ndarray) -> np.ndarray:
    """Angles (rad) within [−π, π), a whole number of turns from ``angle``."""
    return np.remainder(angle + np.pi, 2 * np.pi) - np.pi


def is_real(value: object) -> bool:
    """Whether ``value`` is a real number (Python's or numpy's), not a bool or text."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def is_finite(value: object) -> bool:
    """Whether ``value`` is a finite real number (`is_real`), an integer too large for a float
    included as not finite."""
    try:
        return is_real(value) and math.isfinite(value)  # type: ignore[arg-type]
    except OverflowError:
        return False


def is_whole(value: object, lower: float = -math.inf, upper: float = math.inf) -> bool:
    """Whether ``value`` is a whole number (Python's or numpy's, not a bool) in [lower, upper]."""
    return (
        isinstance(value, int | np.integer)
        and not isinstance(value, bool)
        and bool(lower <= value <= upper)
    )
