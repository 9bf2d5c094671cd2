"""Actuator declarations, read in both forms with one schema (docs/machines.md): an
``[actuators.<name>]`` table of ``robot.toml`` (``kind``, an ActuatorMap subclass by class name;
``joint``; ``stroke = [lower, upper]``, m or rad, unbounded by default; the kind's parameters),
or a URDF ``<transmission>`` of type ``redundancy/<kind>`` (read here with lxml: URDF parsers
drop transmissions), whose one ``<actuator>``, named as the transmission or not at all, holds
the stroke and any ``<cylinder>`` (hydraulic data, as ``[hydraulics.cylinders.<name>]``)::

    <transmission name="x1">
      <type>redundancy/LinearCylinder</type>
      <joint name="boom1_joint"/>
      <actuator name="x1">
        <stroke lower="0.830" upper="1.375"/>
        <cylinder bore="80" rod="45" max_speed="0.25" max_acceleration="1.0"/>
      </actuator>
      <attachment link="column" xyz="0.383 0 -0.964"/>
      <attachment link="boom1" xyz="0.370 0 -0.069"/>
    </transmission>

Transmissions of other types (e.g. ROS ``transmission_interface/SimpleTransmission``) are left
alone.
"""

from __future__ import annotations

import functools
import math
from typing import Any

from lxml import etree
from pydantic import Field, create_model

from redundancy.errors import RobotDescriptionError
from redundancy.model.actuators import ActuatorMap
from redundancy.model.linkage import LinkageCylinder
from redundancy.model.parameters import REQUIRED, number_or_text
from redundancy.model.schema import MAX_OFFSET, CylinderTable, Table, excerpt, toml, validate
from redundancy.model.urdf import written
from redundancy.model.values import is_real

# Kinds are found among ActuatorMap's subclasses: importing a module defines its kinds.
BUNDLED_KINDS = (LinkageCylinder,)

PREFIX = "redundancy/"
_COMMON = ("type", "joint", "actuator")  # a transmission's children that are not parameters


def _kind(kind_name: object, where: str, prefix: str = "") -> type[ActuatorMap]:
    """The kind a declaration names (after ``prefix``), or one line listing the kinds."""
    kinds = ActuatorMap.kinds()
    bare = kind_name[len(prefix) :] if isinstance(kind_name, str) else kind_name
    if not isinstance(kind_name, str) or not kind_name.startswith(prefix) or bare not in kinds:
        raise RobotDescriptionError(
            f"{where} = {excerpt(kind_name, toml)} is not an actuator kind; kinds: "
            f"{', '.join(prefix + k for k in sorted(kinds))}"
        )
    return kinds[bare]  # type: ignore[index]


def _stroke(value: object, kind: type[ActuatorMap], where: str) -> tuple[float, float]:
    """Stroke limits [lower, upper], numbers (infinite ones too) with lower < upper; a cylinder's
    (a ``distance``, m) at least 0 and, where finite, within `MAX_OFFSET`."""
    if (
        not (isinstance(value, list) and len(value) == 2 and all(map(is_real, value)))
        or not value[0] < value[1]
    ):
        raise RobotDescriptionError(
            f"{where} must be [lower, upper], numbers with lower < upper (m, rad for a rotary "
            "drive)"
        )
    lower, upper = float(value[0]), float(value[1])
    if kind.distance and -math.inf < lower < 0:  # an unbounded end, the default, stays one
        raise RobotDescriptionError(
            f"{where}: a cylinder's length is at least 0; its stroke must be too (m)"
        )
    far = [v for v in (lower, upper) if kind.distance and math.isfinite(v) and v > MAX_OFFSET]
    if far:
        raise RobotDescriptionError(
            f"{where}: {far[0]:g} m is beyond {MAX_OFFSET:g} m, longer than any cylinder; did "
            "you give mm? 1 m = 1000 mm"
        )
    return lower, upper


def _declare(
    kind: type[ActuatorMap], name: str, joint: str, given: dict, texts: dict, where: str
) -> ActuatorMap:
    """An actuator of ``kind`` declared by ``where`` (a table or an element): ``given`` maps
    the stroke and each parameter given to its value in the TOML shape, ``texts`` each to
    the file, the actuator and the value as written, or to what is missing."""
    stroke = given.get("stroke", [-math.inf, math.inf])
    lower, upper = _stroke(stroke, kind, texts.get("stroke", ""))
    values: dict[str, Any] = {}
    for parameter in kind.parameters:
        if parameter.name in given:
            values[parameter.name] = parameter.read(given[parameter.name], texts[parameter.name])
        elif parameter.default is REQUIRED:
            raise RobotDescriptionError(f"{texts[parameter.name]} ({parameter.meaning})")
        else:
            values[parameter.name] = parameter.default
    actuator = kind(name, joint, lower, upper, **values)
    actuator.declared_in = where
    return actuator


@functools.cache
def _table(kind: type[ActuatorMap]) -> type[Table]:
    """The ``[actuators.<name>]`` table of ``kind``: its keys, the joint a name (the stroke and
    the parameters are read as in a URDF)."""
    names = ["stroke", *(parameter.name for parameter in kind.parameters)]
    keys: dict[str, Any] = dict.fromkeys(names, (Any, None))
    return create_model(
        f"{kind.__name__}Table",
        __base__=Table,
        kind=(str, ...),
        joint=(str, Field(description="the joint it drives")),
        **keys,
    )


def read_actuator_tables(tables: dict[str, dict], source: str) -> list[ActuatorMap]:
    """The actuators of ``robot.toml``'s ``[actuators.<name>]`` tables (``tables``: the
    ``actuators`` table); ``source`` names the file in errors."""
    maps = []
    for name, table in tables.items():
        where = f"{source}: [actuators.{name}]"
        kind = _kind(table.get("kind"), f"{where} kind")
        joint = validate(_table(kind), table, source, f"actuators.{name}", RobotDescriptionError)
        texts = {p.name: f"{where}: missing key {p.name}" for p in kind.parameters}
        texts |= {key: f"{where} {key} = {excerpt(value, toml)}" for key, value in table.items()}
        maps.append(_declare(kind, name, joint.joint, table, texts, where))  # type: ignore[attr-defined]
    return maps


def redundancy_transmissions(root: etree._Element) -> list[etree._Element]:
    return [
        element
        for element in root.findall("transmission")
        if (element.findtext("type") or "").strip().startswith(PREFIX)
    ]


def _read_transmission(element: etree._Element, source: str) -> ActuatorMap:
    """The actuator a ``<transmission>`` of the redundancy types declares (module docstring)."""
    name = element.get("name")
    where = f"{source}: <transmission name={name!r}>"
    kind = _kind((element.findtext("type") or "").strip(), f"{where} <type>", PREFIX)
    joint = _check_header(element, where)
    given: dict[str, object] = {}
    texts: dict[str, str] = {}
    stroke = element.find("actuator/stroke")
    if stroke is not None:
        texts["stroke"] = f"{where} {written(stroke)}"
        bounds = (stroke.get("lower", "-inf"), stroke.get("upper", "inf"))
        given["stroke"] = [number_or_text(text) for text in bounds]
    # parameters sharing a tag take its elements in turn
    children = {
        tag: iter(found) for tag, found in _parameter_elements(element, kind, where).items()
    }
    for parameter in kind.parameters:
        child = next(children.get(parameter.element, iter(())), None)
        if child is not None:
            given[parameter.name] = parameter.from_attributes(dict(child.attrib))
            texts[parameter.name] = f"{where} {parameter.name} {written(child)}"
        else:
            texts[parameter.name] = f"{where}: missing <{parameter.element}> for {parameter.name}"
    return _declare(kind, str(name), joint, given, texts, where)


def _check_header(element: etree._Element, where: str) -> str:
    """The joint a ``<transmission>`` drives, once it has a name, one ``<joint name=...>`` and
    at most one ``<actuator>``, named as itself or not at all."""
    name = element.get("name")
    joints = element.findall("joint")
    if not name or len(joints) != 1 or not joints[0].get("name"):
        raise RobotDescriptionError(
            f"{where} needs a name and exactly one <joint name=...>; it has {len(joints)} "
            "joint elements"
        )
    actuators = element.findall("actuator")
    if len(actuators) > 1:
        raise RobotDescriptionError(
            f"{where} has {len(actuators)} <actuator> elements; it declares one actuator, "
            f'itself: <actuator name="{name}">'
        )
    if actuators and actuators[0].get("name", name) != name:
        raise RobotDescriptionError(
            f'{where} <actuator name="{actuators[0].get("name")}"> must be named {name!r}: the '
            "actuator is the transmission itself, and takes its name (or none)"
        )
    return str(joints[0].get("name"))


def _parameter_elements(
    element: etree._Element, kind: type[ActuatorMap], where: str
) -> dict[str, list[etree._Element]]:
    """A ``<transmission>``'s children that give the kind's parameters, by tag; more of a tag
    than the kind takes is refused, naming the kind's elements."""
    children: dict[str, list[etree._Element]] = {}
    for child in element:
        if isinstance(child.tag, str) and child.tag not in _COMMON:
            children.setdefault(child.tag, []).append(child)
    tags = [p.element for p in kind.parameters]
    for tag, found in children.items():
        if tags.count(tag) < len(found):
            expected = [p.name for p in kind.parameters if p.element == tag]
            raise RobotDescriptionError(
                f"{where}: {len(found)} <{tag}> elements; {kind.__name__} takes "
                + (f"{len(expected)} ({', '.join(expected)})" if expected else "none")
                + f"; its elements: {', '.join(f'<{t}>' for t in dict.fromkeys(tags)) or 'none'}"
            )
    return children


def read_transmissions(root: etree._Element, source: str) -> list[ActuatorMap]:
    """The actuator maps declared in a URDF's root element; ``source`` names it in errors."""
    return [_read_transmission(element, source) for element in redundancy_transmissions(root)]


def read_cylinders(root: etree._Element, source: str) -> dict[str, CylinderTable]:
    """The hydraulic data of the cylinders declared in a URDF's redundancy transmissions, by
    actuator name: each ``<actuator><cylinder .../></actuator>`` element's attributes, read as
    a ``[hydraulics.cylinders.<name>]`` table (`redundancy.model.schema.CylinderTable`)."""
    found = {}
    for element in redundancy_transmissions(root):
        name = element.get("name") or ""
        for cylinder in element.findall("actuator/cylinder"):
            values = {key: number_or_text(text) for key, text in cylinder.attrib.items()}
            where = f"{source}: <transmission name={name!r}> <cylinder>"
            found[name] = validate(
                CylinderTable, values, where, error=RobotDescriptionError, entries="attributes"
            )
    return found
