"""Typed values from description files (robot.toml, task.toml, hydraulics), checked at the door.

Every reader names, on failure, the file and key the value came from, what it must be and its
range, in one line (`InvalidInputError`). A string is never read as a list of its characters.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Collection
from pathlib import Path

import numpy as np

from redundancy.errors import InvalidInputError

REQUIRED = object()  # the default of a key that must be given

MAX_PAYLOAD = 1e5  # kg: beyond any hydraulic machine this toolkit models
MAX_SPEED = 10.0  # m/s along a task path: beyond any hydraulic manipulator's tool


def read_toml(path: Path, what: str) -> dict:
    """The tables of the TOML file ``path`` (a ``what``, e.g. "task file"), or one line."""
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except OSError as error:
        raise InvalidInputError(f"cannot read {what} {path}: {error.strerror}") from None
    except UnicodeDecodeError:
        raise InvalidInputError(f"{path}: not a {what}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as error:
        raise InvalidInputError(f"{path}: not valid TOML: {error}") from None


def refuse_unknown(
    table: Collection[str],
    known: Collection[str],
    where: str,
    what: str = "keys",
    error: type[Exception] = InvalidInputError,
) -> None:
    """Refuse the entries of ``table`` (its keys, from ``where``) that are not among ``known``:
    one ``error`` naming them, ``where`` and the ``known`` ones (``what`` they are: keys,
    attributes, parameters)."""
    extra = sorted(set(table) - set(known))
    if extra:
        raise error(f"{where}: unknown {what} {extra}; {what}: {', '.join(known)}")


def _given(table: dict, key: str, where: str, meaning: str, default):
    if key in table:
        return table[key]
    if default is REQUIRED:
        raise InvalidInputError(f"{where}: missing {key!r} ({meaning})")
    return default


def number(
    table: dict,
    key: str,
    where: str,
    meaning: str,
    default=REQUIRED,
    lower: float = -math.inf,
    upper: float = math.inf,
) -> float:
    """``table[key]`` as a finite number in [lower, upper] (``default`` when absent)."""
    if key not in table and default is not REQUIRED:
        return default
    value = _given(table, key, where, meaning, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InvalidInputError(f"{where}: {key} = {value!r} must be a finite number ({meaning})")
    if not lower <= value <= upper:
        raise InvalidInputError(
            f"{where}: {key} = {value!r} must be within [{lower:g}, {upper:g}] ({meaning})"
        )
    return float(value)


def text(table: dict, key: str, where: str, meaning: str, default=REQUIRED) -> str:
    """``table[key]`` as a string (``default`` when absent)."""
    if key not in table and default is not REQUIRED:
        return default
    value = _given(table, key, where, meaning, default)
    if not isinstance(value, str):
        raise InvalidInputError(f"{where}: {key} = {value!r} must be a string ({meaning})")
    return value


def names(
    table: dict, key: str, where: str, meaning: str, default=(), distinct: bool = False
) -> tuple[str, ...]:
    """``table[key]`` as a list of strings, each given once where ``distinct``; a bare string
    is refused, not split."""
    value = _given(table, key, where, meaning, default)
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise InvalidInputError(
            f'{where}: {key} = {value!r} must be a list of names, e.g. {key} = ["..."] ({meaning})'
        )
    repeated = sorted({v for v in value if value.count(v) > 1})
    if distinct and repeated:
        raise InvalidInputError(
            f"{where}: {key} = {value!r} names {', '.join(map(repr, repeated))} more than once; "
            f"give each once ({meaning})"
        )
    return tuple(value)


def decimal(text: str) -> float:
    """The number ``text`` writes, in the notation files and options use (``-1.5``, ``2e-3``,
    ``inf``, ``nan``); `ValueError` for anything else, Python's ``1_000`` included."""
    if "_" in text:
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def is_real(value: object) -> bool:
    """Whether ``value`` is a real number (Python's or numpy's), not a bool or text."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def is_whole(value: object, lower: float = -math.inf, upper: float = math.inf) -> bool:
    """Whether ``value`` is a whole number (Python's or numpy's, not a bool) in [lower, upper]."""
    return (
        isinstance(value, int | np.integer)
        and not isinstance(value, bool)
        and bool(lower <= value <= upper)
    )


def coordinates(value: object, where: str, dimension: int | None) -> np.ndarray:
    """``value`` as finite coordinates, ``dimension`` of them where given."""
    if not isinstance(value, list) or not all(is_real(v) for v in value):
        raise InvalidInputError(f"{where} = {value!r} must be a list of numbers")
    array = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise InvalidInputError(f"{where} = {value!r} must be finite")
    if dimension is not None and array.shape != (dimension,):
        raise InvalidInputError(
            f"{where} has {array.size} coordinates; the robot's task has {dimension}"
        )
    return array
