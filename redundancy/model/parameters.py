"""An actuator kind's parameters: one schema for both ways of declaring an actuator.

A kind lists its parameters once (`redundancy.model.actuators.ActuatorMap.parameters`); each
knows its value's shape as an ``[actuators.<name>]`` key and as a ``<transmission>`` child
(`redundancy.model.transmissions`), named after the parameter unless it gives a ``tag``
(parameters sharing a tag take its elements in turn: a cylinder's base, then rod). Both forms
are checked by the one `Parameter.read`, so they give the same one-line errors.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import AfterValidator, AllowInfNan, Strict, TypeAdapter, ValidationError

from redundancy.errors import RobotDescriptionError
from redundancy.model.schema import DECLARED, MAX_OFFSET, ArmOnLink, PointOnLink
from redundancy.model.values import decimal

REQUIRED = object()  # the default of a parameter that must be given


@dataclass(frozen=True)
class Parameter:
    """One parameter of an actuator kind: its ``name`` (the TOML key, the constructor's keyword
    and the instances' attribute), what it means (with its unit), its ``default`` (`REQUIRED`
    when it must be given) and its ``<transmission>`` child's ``tag`` (the name when empty).
    A kind's value is checked by its pydantic ``annotation`` and described by its ``shape``."""

    name: str
    meaning: str
    default: object = REQUIRED
    tag: str = ""
    annotation: ClassVar[Any] = None  # Number and Choice set their own on creation
    shape: ClassVar[str] = ""

    @property
    def element(self) -> str:
        return self.tag or self.name

    def read(self, value: object, where: str) -> Any:
        """The value from its TOML shape, as the kind's constructor takes it; ``where`` names
        the file, the actuator and the value as written, for the message."""
        try:
            return self.convert(TypeAdapter(self.annotation).validate_python(value))
        except ValidationError as error:
            declared = [e for e in error.errors() if e["type"] == DECLARED]
            if declared:  # a rule of the schema's own, whose words name the value and the fix
                field = ".".join(str(part) for part in declared[0]["loc"])
                said = f"{where}: {field} {declared[0]['msg']}"
                raise RobotDescriptionError(f"{said} ({self.meaning})") from None
            raise RobotDescriptionError(f"{where} must be {self.shape} ({self.meaning})") from None

    def convert(self, value: Any) -> Any:
        return value

    def from_attributes(self, attributes: dict[str, str]) -> object:
        """A ``<transmission>`` child's attributes in the TOML shape, unchecked: text that is
        not a number stays text, so that `read` names it."""
        return number_or_text(attributes.get("value", ""))


def number_or_text(text: str) -> float | str:
    """An attribute's text as a number, or the text itself where it is none (for the message)."""
    try:
        return decimal(text)
    except ValueError:
        return text


@dataclass(frozen=True)
class Number(Parameter):
    """A finite number (``<tag value="..."/>``), e.g. a prismatic drive's offset in m; one of
    ``allowed`` where it is given (a linkage's assembly branch, 1 or -1)."""

    allowed: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        check = AfterValidator(self._allowed) if self.allowed else AllowInfNan(False)
        object.__setattr__(self, "annotation", Annotated[float, Strict(), check])
        shape = f"one of {', '.join(f'{a:g}' for a in self.allowed)}"
        object.__setattr__(self, "shape", shape if self.allowed else "a finite number")

    def _allowed(self, value: float) -> float:
        if value not in self.allowed:
            raise ValueError(value)
        return value


@dataclass(frozen=True)
class Choice(Parameter):
    """One of a closed set of words (``<tag value="..."/>``)."""

    choices: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "annotation", Literal[self.choices])
        object.__setattr__(self, "shape", f"one of {', '.join(map(repr, self.choices))}")

    def from_attributes(self, attributes: dict[str, str]) -> object:
        return attributes.get("value", "")


@dataclass(frozen=True)
class Point(Parameter):
    """A point fixed on a link: ``(link, xyz)`` with xyz (3,) in m in the link's frame;
    ``{link = "...", xyz = [x, y, z]}`` in TOML, ``<tag link="..." xyz="x y z"/>`` in a URDF."""

    annotation: ClassVar[Any] = PointOnLink
    shape = (
        f'{{link = "<a link>", xyz = [x, y, z]}} with three numbers within '
        f"±{MAX_OFFSET:g} m (in m: 1 m = 1000 mm)"
    )

    def convert(self, value: PointOnLink) -> tuple[str, np.ndarray]:
        return value.link, np.array(value.xyz)

    def from_attributes(self, attributes: dict[str, str]) -> object:
        found: dict[str, object] = dict(attributes)
        if "xyz" in attributes:
            found["xyz"] = [number_or_text(c) for c in attributes["xyz"].split()]
        if "length" in attributes:
            found["length"] = number_or_text(attributes["length"])
        return found


@dataclass(frozen=True)
class Arm(Point):
    """A point fixed on a link and a length from it: ``(link, xyz, length)``, xyz (3,) and the
    length > 0 in m; ``{link = "...", xyz = [x, y, z], length = l}`` in TOML,
    ``<tag link="..." xyz="x y z" length="l"/>`` in a URDF (a linkage's rocker: its pivot and
    its length to the rod's pin)."""

    annotation: ClassVar[Any] = ArmOnLink
    shape = (
        f'{{link = "<a link>", xyz = [x, y, z], length = l}} with numbers within '
        f"±{MAX_OFFSET:g} m, l > 0 (in m: 1 m = 1000 mm)"
    )

    def convert(self, value: ArmOnLink) -> tuple[str, np.ndarray, float]:  # type: ignore[override]
        return value.link, np.array(value.xyz), value.length
