"""An actuator kind's parameters: one schema for both ways of declaring an actuator.

An actuator is declared either as an ``[actuators.<name>]`` table of ``robot.toml`` or as a
``<transmission>`` element of the URDF (`redundancy.model.transmissions`). A kind lists its
parameters once (`redundancy.model.actuators.ActuatorMap.parameters`), and each parameter knows
its value's shape in both forms:

- `Number`: ``offset = -0.18`` and ``<offset value="-0.18"/>``;
- `Point`: ``base = {link = "column", xyz = [0, 0, 1]}`` and
  ``<attachment link="column" xyz="0 0 1"/>``;
- `Choice`: ``side = "left"`` and ``<side value="left"/>``;
- `Arm`: a point and a length from it, ``rocker = {link = "stick", xyz = [1.5, 0, 0.07],
  length = 0.45}`` and ``<rocker link="stick" xyz="1.5 0 0.07" length="0.45"/>``.

A parameter's child element is named after it unless it gives a ``tag``; parameters sharing a
tag take that tag's elements in the order they are listed (a cylinder's two ``<attachment>``s:
base, then rod). A value read from either form is checked by the one `Parameter.read`, so both
forms give the same one-line errors, each naming the value as written.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import cast

import numpy as np

from redundancy.errors import RobotDescriptionError
from redundancy.model.schema import MAX_OFFSET
from redundancy.model.values import decimal

REQUIRED = object()  # the default of a parameter that must be given


@dataclass(frozen=True)
class Parameter(ABC):
    """One parameter of an actuator kind: its ``name`` (the TOML key and the attribute of the
    kind's instances, and the constructor's keyword), what it means (with its unit), its
    ``default`` (`REQUIRED` when it must be given) and its ``<transmission>`` child's ``tag``
    (the name when empty)."""

    name: str
    meaning: str
    default: object = REQUIRED
    tag: str = ""

    @property
    def element(self) -> str:
        """The tag of its ``<transmission>`` child."""
        return self.tag or self.name

    def _refuse(self, where: str, shape: str) -> RobotDescriptionError:
        return RobotDescriptionError(f"{where} must be {shape} ({self.meaning})")

    @abstractmethod
    def read(self, value: object, where: str) -> object:
        """The value from its TOML shape (or an element's attributes turned into that shape);
        ``where`` names the file, the actuator and the value as written, for the message."""

    @abstractmethod
    def from_attributes(self, attributes: dict[str, str]) -> object:
        """A ``<transmission>`` child's attributes in the TOML shape, unchecked: text that is
        not a number stays text, so that `read` names it."""


def number_or_text(text: str) -> float | str:
    """An attribute's text as a number, or the text itself where it is none (for the message)."""
    try:
        return decimal(text)
    except ValueError:
        return text


def _finite(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _offset(value: object) -> bool:
    """A finite coordinate or length of a link's point, within `MAX_OFFSET`."""
    return _finite(value) and abs(cast(float, value)) <= MAX_OFFSET


@dataclass(frozen=True)
class Number(Parameter):
    """A finite number (``<tag value="..."/>``), e.g. a prismatic drive's offset in m; one of
    ``allowed`` where it is given (a linkage's assembly branch, 1 or -1)."""

    allowed: tuple[float, ...] = ()

    def read(self, value: object, where: str) -> float:
        if not _finite(value):
            raise self._refuse(where, "a finite number")
        if self.allowed and value not in self.allowed:
            raise self._refuse(where, f"one of {', '.join(f'{a:g}' for a in self.allowed)}")
        return float(value)  # type: ignore[arg-type]

    def from_attributes(self, attributes: dict[str, str]) -> object:
        return number_or_text(attributes.get("value", ""))


@dataclass(frozen=True)
class Choice(Parameter):
    """One of a closed set of words (``<tag value="..."/>``)."""

    choices: tuple[str, ...] = ()

    def read(self, value: object, where: str) -> str:
        if value not in self.choices:
            raise self._refuse(where, f"one of {', '.join(map(repr, self.choices))}")
        return str(value)

    def from_attributes(self, attributes: dict[str, str]) -> object:
        return attributes.get("value", "")


@dataclass(frozen=True)
class Point(Parameter):
    """A point fixed on a link: ``(link, xyz)`` with xyz (3,) in m in the link's frame;
    ``{link = "...", xyz = [x, y, z]}`` in TOML, ``<tag link="..." xyz="x y z"/>`` in a URDF."""

    def read(self, value: object, where: str) -> tuple[str, np.ndarray]:
        shape = (
            f'{{link = "<a link>", xyz = [x, y, z]}} with three numbers within ±{MAX_OFFSET:g} m '
            "(in m: 1 m = 1000 mm)"
        )
        if not isinstance(value, dict) or set(value) != {"link", "xyz"}:
            raise self._refuse(where, shape)
        link, xyz = value["link"], value["xyz"]
        if (
            not isinstance(link, str)
            or not isinstance(xyz, list)
            or len(xyz) != 3
            or not all(_offset(c) for c in xyz)
        ):
            raise self._refuse(where, shape)
        return link, np.array(xyz, dtype=float)

    def from_attributes(self, attributes: dict[str, str]) -> object:
        found: dict[str, object] = dict(attributes)
        if "xyz" in attributes:
            found["xyz"] = [number_or_text(c) for c in attributes["xyz"].split()]
        return found


@dataclass(frozen=True)
class Arm(Parameter):
    """A point fixed on a link and a length from it: ``(link, xyz, length)``, xyz (3,) and the
    length > 0 in m; ``{link = "...", xyz = [x, y, z], length = l}`` in TOML,
    ``<tag link="..." xyz="x y z" length="l"/>`` in a URDF (a linkage's rocker: its pivot and
    its length to the rod's pin)."""

    @property
    def _point(self) -> Point:
        return Point(self.name, self.meaning)

    def read(self, value: object, where: str) -> tuple[str, np.ndarray, float]:
        shape = (
            f'{{link = "<a link>", xyz = [x, y, z], length = l}} with numbers within '
            f"±{MAX_OFFSET:g} m, l > 0 (in m: 1 m = 1000 mm)"
        )
        if not isinstance(value, dict) or set(value) != {"link", "xyz", "length"}:
            raise self._refuse(where, shape)
        length = value["length"]
        if not _offset(length) or not length > 0:
            raise self._refuse(where, shape)
        try:
            link, xyz = self._point.read({"link": value["link"], "xyz": value["xyz"]}, where)
        except RobotDescriptionError:
            raise self._refuse(where, shape) from None
        return link, xyz, float(length)

    def from_attributes(self, attributes: dict[str, str]) -> object:
        found = cast(dict[str, object], self._point.from_attributes(attributes))
        if "length" in attributes:
            found["length"] = number_or_text(attributes["length"])
        return found
