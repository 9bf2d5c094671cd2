"""Actuator declarations written in both forms, for the tests that read them back: the inverse of
the readers of `redundancy.model.transmissions` (``[actuators.<name>]`` tables and URDF
``<transmission>``s)."""

import math
import re

from lxml import etree

from redundancy.model.actuators import ActuatorMap
from redundancy.model.parameters import Arm, Choice, Parameter, Point
from redundancy.model.transmissions import PREFIX, redundancy_transmissions


def table_value(parameter: Parameter, value: object) -> object:
    """A parameter's value in its TOML shape."""
    if isinstance(parameter, Arm):
        link, xyz, length = value
        return {"link": link, "xyz": [float(c) for c in xyz], "length": float(length)}
    if isinstance(parameter, Point):
        link, xyz = value
        return {"link": link, "xyz": [float(c) for c in xyz]}
    return str(value) if isinstance(parameter, Choice) else float(value)


def attributes(parameter: Parameter, value: object) -> dict[str, str]:
    """A parameter's value as its ``<transmission>`` child's attributes."""
    given = table_value(parameter, value)
    if not isinstance(given, dict):
        return {"value": given if isinstance(given, str) else repr(given)}
    return {
        key: " ".join(map(repr, v)) if isinstance(v, list) else v if isinstance(v, str) else repr(v)
        for key, v in given.items()
    }


def write_transmissions(urdf: str, actuators: list[ActuatorMap]) -> str:
    """``urdf`` text with its redundancy transmissions replaced by declarations of ``actuators``."""
    root = etree.fromstring(urdf.encode())
    for element in redundancy_transmissions(root):
        root.remove(element)
    for actuator in actuators:
        element = etree.SubElement(root, "transmission", name=actuator.name)
        etree.SubElement(element, "type").text = PREFIX + type(actuator).__name__
        etree.SubElement(element, "joint", name=actuator.joint)
        declared = etree.SubElement(element, "actuator", name=actuator.name)
        etree.SubElement(declared, "stroke", lower=repr(actuator.lower), upper=repr(actuator.upper))
        for parameter in type(actuator).parameters:
            value = getattr(actuator, parameter.name)
            etree.SubElement(element, parameter.element, **attributes(parameter, value))
    etree.indent(root, space="  ")
    return etree.tostring(root, encoding="unicode", xml_declaration=False) + "\n"


def actuator_tables(actuators: list[ActuatorMap]) -> dict[str, dict[str, object]]:
    """The ``[actuators.<name>]`` tables declaring ``actuators``."""
    return {
        actuator.name: {
            "kind": type(actuator).__name__,
            "joint": actuator.joint,
            "stroke": [actuator.lower, actuator.upper],
            **{
                p.name: table_value(p, getattr(actuator, p.name)) for p in type(actuator).parameters
            },
        }
        for actuator in actuators
    }


def _toml(value: object) -> str:
    """A value of an actuator table (text, number, list, inline table) in TOML."""
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    return repr(value)


def write_actuator_tables(actuators: list[ActuatorMap]) -> str:
    """TOML text of the ``[actuators.<name>]`` tables declaring ``actuators``."""
    blocks = []
    for name, table in actuator_tables(actuators).items():
        key = name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _toml(name)
        lines = [f"[actuators.{key}]", *(f"{k} = {_toml(v)}" for k, v in table.items())]
        blocks.append("\n".join(lines) + "\n")
    return "\n".join(blocks)
