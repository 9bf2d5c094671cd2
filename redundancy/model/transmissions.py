"""Actuator declarations in URDF ``<transmission>`` elements: reading and writing.

URDF parsers (urdfdom under Pinocchio, yourdfpy) drop transmissions, so they are read here with
lxml. Schema::

    <transmission name="x1">                        <!-- the actuator's name -->
      <type>redundancy/LinearCylinder</type>        <!-- redundancy/<ActuatorMap subclass> -->
      <joint name="boom1_joint"/>                   <!-- the joint it drives -->
      <actuator name="x1">
        <stroke lower="0.830" upper="1.375"/>       <!-- stroke limits, m (rad for rotary) -->
        <cylinder bore="80" rod="45" max_speed="0.25" max_acceleration="1.0"/>
      </actuator>                                   <!-- optional hydraulic data: mm, m/s, m/s² -->
      <attachment link="column" xyz="..."/>         <!-- kind-specific children: a cylinder's -->
      <attachment link="boom1" xyz="..."/>          <!-- base point, then its rod point -->
    </transmission>

``Prismatic`` takes ``<offset value="..."/>`` (x = q + offset); ``Identity`` nothing more;
``LinkageCylinder`` (`redundancy.model.linkage`) its ``PARAMETERS``: ``<base link xyz>``,
``<rocker link xyz length>``, ``<coupler link xyz length>`` and ``<branch value>``. A kind
of your own takes whatever children its ``from_transmission`` reads. Transmissions of other types
(e.g. ROS ``transmission_interface/SimpleTransmission``) are left alone. A ``<cylinder>`` in the
``<actuator>`` gives the cylinder's hydraulic data, as a ``[hydraulics.cylinders.<name>]`` table
of ``robot.toml`` does (`redundancy.model.hydraulics`; the machine's supply stays in the TOML).
"""

from __future__ import annotations

from lxml import etree

from redundancy.errors import RobotDescriptionError
from redundancy.model.actuators import ActuatorMap
from redundancy.model.hydraulics import CYLINDER_KEYS
from redundancy.model.linkage import LinkageCylinder

# The kinds are found by class name among ActuatorMap's subclasses: the bundled ones beyond
# actuators.py are defined by importing their modules.
BUNDLED_KINDS = (LinkageCylinder,)

PREFIX = "redundancy/"
_COMMON = {"type", "joint", "actuator"}


def _number(source: str, name: str, element: etree._Element, key: str, default: float) -> float:
    text = element.get(key)
    if text is None:
        return default
    try:
        return float(text)
    except ValueError as error:
        raise RobotDescriptionError(
            f"{source}: transmission {name!r}: {key}={text!r} is not a number"
        ) from error


def _read_one(element: etree._Element, source: str) -> ActuatorMap:
    name = element.get("name")
    kind_name = (element.findtext("type") or "").strip()[len(PREFIX) :]
    kinds = ActuatorMap.kinds()
    if kind_name not in kinds:
        raise RobotDescriptionError(
            f"{source}: transmission {name!r} has unknown type {PREFIX}{kind_name}; "
            f"known: {', '.join(PREFIX + k for k in sorted(kinds))}"
        )
    joints = element.findall("joint")
    if not name or len(joints) != 1 or not joints[0].get("name"):
        raise RobotDescriptionError(
            f"{source}: transmission {name!r} needs a name and exactly one <joint name=...>; "
            f"it has {len(joints)} joint elements"
        )
    stroke = element.find("actuator/stroke")
    lower = upper = None
    if stroke is not None:
        lower = _number(source, name, stroke, "lower", float("-inf"))
        upper = _number(source, name, stroke, "upper", float("inf"))
    data: dict[str, list[dict]] = {}
    for child in element:
        if isinstance(child.tag, str) and child.tag not in _COMMON:
            data.setdefault(child.tag, []).append(dict(child.attrib))
    actuator = kinds[kind_name].from_transmission(
        name,
        joints[0].get("name"),
        float("-inf") if lower is None else lower,
        float("inf") if upper is None else upper,
        data,
    )
    return actuator


def read_cylinders(root: etree._Element, source: str) -> dict[str, dict[str, float]]:
    """The hydraulic data of the cylinders declared in a URDF's redundancy transmissions, by
    actuator name: each ``<actuator><cylinder .../></actuator>`` element's attributes as numbers
    (`CYLINDER_KEYS`; missing ones are left for `circuit_from_table` to name)."""
    found = {}
    for element in root.findall("transmission"):
        if not (element.findtext("type") or "").strip().startswith(PREFIX):
            continue
        name = element.get("name") or ""
        for cylinder in element.findall("actuator/cylinder"):
            extra = sorted(set(cylinder.attrib) - set(CYLINDER_KEYS))
            if extra:
                raise RobotDescriptionError(
                    f"{source}: transmission {name!r}: <cylinder> has unknown attributes "
                    f"{extra}; attributes: {', '.join(CYLINDER_KEYS)}"
                )
            found[name] = {
                key: _number(source, name, cylinder, key, float("nan"))
                for key in CYLINDER_KEYS
                if key in cylinder.attrib
            }
    return found


def read_transmissions(root: etree._Element, source: str) -> list[ActuatorMap]:
    """The actuator maps declared in a URDF's root element; ``source`` names it in errors."""
    return [
        _read_one(element, source)
        for element in root.findall("transmission")
        if (element.findtext("type") or "").strip().startswith(PREFIX)
    ]


def write_transmissions(urdf: str, actuators: list[ActuatorMap]) -> str:
    """``urdf`` text with its redundancy transmissions replaced by declarations of ``actuators``."""
    root = etree.fromstring(urdf.encode())
    for element in root.findall("transmission"):
        if (element.findtext("type") or "").strip().startswith(PREFIX):
            root.remove(element)
    for actuator in actuators:
        element = etree.SubElement(root, "transmission", name=actuator.name)
        etree.SubElement(element, "type").text = PREFIX + type(actuator).__name__
        etree.SubElement(element, "joint", name=actuator.joint)
        declared = etree.SubElement(element, "actuator", name=actuator.name)
        etree.SubElement(declared, "stroke", lower=repr(actuator.lower), upper=repr(actuator.upper))
        for tag, items in actuator.transmission_data().items():
            for attributes in items:
                etree.SubElement(element, tag, **attributes)
    etree.indent(root, space="  ")
    return etree.tostring(root, encoding="unicode", xml_declaration=False) + "\n"
