"""Write excavator.urdf: a hydraulic excavator's boom, stick and bucket in the vertical plane.

Run ``python generate.py`` from anywhere. Every number is in README.md with its source; the
pin coordinates are given in each link's own frame, whose x axis runs from the link's joint to
its next joint (the bucket's: from the bucket joint to the coupler pin). The joint value is the
link's angle to its parent's x axis, counterclockwise in the world x–z plane (axes are world
−y), so the source's reference pose is q = (30°, −60°, 70°). Joint limits are the images of the
stroke limits, found with the toolkit itself on a copy of the URDF without them.
"""

import tempfile
from math import cos, radians, sin
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

# Pin coordinates (m), each in its link's frame, (x, z).
SWING_HEIGHT = 0.767  # the chassis's turning joint above the ground (B)
BOOM_PIVOT = (0.3256, 0.389)  # C on the chassis
BOOM_CYLINDER_BASE = (0.800, 0.152)  # D on the chassis
BOOM_CYLINDER_ROD = (1.532, 0.686)  # E on the boom
BOOM_LENGTH = 3.845  # C to H, the stick joint
STICK_CYLINDER_BASE = (2.1653, 0.9437)  # F on the boom
STICK_CYLINDER_ROD = (-0.551, 0.147)  # G on the stick
STICK_LENGTH = 1.996  # H to M, the bucket joint
BUCKET_CYLINDER_BASE = (0.2402, 0.3782)  # I on the stick
ROCKER_PIVOT = (1.522, 0.065)  # K on the stick
ROCKER_LENGTH = 0.4539  # K to J, the pin of rocker, coupler and bucket cylinder rod
COUPLER_PIN = (0.379, 0.0)  # L on the bucket
COUPLER_LENGTH = 0.449  # J to L
BRANCH = 1  # the closure the source's reference pose assembles (a test checks its lengths)
# Assumption (see README.md): the bucket's teeth, TIP_RADIUS from the bucket joint, TIP_ANGLE
# clockwise from the bucket's x axis.
TIP_RADIUS, TIP_ANGLE = 1.0, 95.0

# Assumption (see README.md): the bucket cylinder's closed length. The source's (0.15 + 0.8656 m)
# is shorter than the linkage allows (1.081 m, at a dead point where the cylinder loses its
# lever); this one stops the bucket 16 degrees before that dead point.
BUCKET_CLOSED = 1.112
# Strokes: cylinder lengths (m), pin to pin, the source's piston travel plus its rod length.
STROKES = {
    "boom": (0.06 + 1.336, 0.56 + 1.336),
    "stick": (0.28 + 1.147, 0.93 + 1.147),
    "bucket": (BUCKET_CLOSED, 0.65 + 0.8656),
}
REFERENCE = {"boom": 30.0, "stick": -60.0, "bucket": 70.0}  # degrees, the source's pose

# Masses (kg), centres of mass (x, z) in the link frame (m), and inertias about the centre of
# mass (kg m²) with the link frame's axes: ixx, iyy (about the joint axis), izz, ixy, ixz, iyz.
INERTIAS = {
    "boom": (1600.0, (1.729, 0.463), (87.0, 1768.0, 1690.0, -0.2, -14.0, 0.02)),
    "stick": (880.0, (0.476, 0.119), (15.0, 302.0, 290.0, -0.2, 23.0, 0.02)),
    "bucket": (450.0, (0.231, -0.468), (77.0, 65.0, 55.0, -0.2, -11.0, 0.02)),
}

# Not in the source: URDF <limit> effort and velocity ratings (unused by the toolkit) and the
# drawn boxes' sizes (m).
EFFORT, VELOCITY = 1.0e6, 1.0
WIDTH = {"chassis": 2.2, "boom": 0.30, "stick": 0.22, "bucket": 0.70}
JOINT_OF = {"boom": "boom_joint", "stick": "stick_joint", "bucket": "bucket_joint"}
PARENT_OF = {"boom": "chassis", "stick": "boom", "bucket": "stick"}
ORIGIN_OF = {"boom": BOOM_PIVOT, "stick": (BOOM_LENGTH, 0.0), "bucket": (STICK_LENGTH, 0.0)}


def _num(value: float) -> str:
    return f"{value:.15g}"


def _xyz(x: float, y: float, z: float) -> str:
    return " ".join(_num(v) for v in (x, y, z))


def _point(xz: tuple[float, float]) -> str:
    return _xyz(xz[0], 0.0, xz[1])


def _box(centre: tuple[float, float], length: float, height: float, width: float, angle=0.0):
    return f"""    <visual>
      <origin xyz="{_point(centre)}" rpy="{_xyz(0, -angle, 0)}"/>
      <geometry><box size="{_xyz(length, width, height)}"/></geometry>
      <material name="steel"/>
    </visual>
"""


def _link(name: str) -> str:
    mass, (cx, cz), (ixx, iyy, izz, ixy, ixz, iyz) = INERTIAS[name]
    if name == "bucket":
        tip = TIP_RADIUS * cos(radians(-TIP_ANGLE)), TIP_RADIUS * sin(radians(-TIP_ANGLE))
        shape = _box((tip[0] / 2, tip[1] / 2), TIP_RADIUS, 0.35, WIDTH[name], radians(-TIP_ANGLE))
    else:
        length = BOOM_LENGTH if name == "boom" else STICK_LENGTH
        shape = _box((length / 2, 0.0), length, WIDTH[name], WIDTH[name])
    return f"""  <link name="{name}">
    <inertial>
      <origin xyz="{_xyz(cx, 0, cz)}"/>
      <mass value="{_num(mass)}"/>
      <inertia ixx="{_num(ixx)}" ixy="{_num(ixy)}" ixz="{_num(ixz)}" iyy="{_num(iyy)}" iyz="{_num(iyz)}" izz="{_num(izz)}"/>
    </inertial>
{shape}  </link>
"""


def _joint(name: str, limits: tuple[float, float]) -> str:
    return f"""  <joint name="{JOINT_OF[name]}" type="revolute">
    <parent link="{PARENT_OF[name]}"/>
    <child link="{name}"/>
    <origin xyz="{_point(ORIGIN_OF[name])}"/>
    <axis xyz="0 -1 0"/>
    <limit lower="{_num(limits[0])}" upper="{_num(limits[1])}" effort="{EFFORT:g}" velocity="{VELOCITY:g}"/>
  </joint>
"""


def _stroke(name: str) -> str:
    lower, upper = STROKES[name]
    return (
        f'<actuator name="{name}"><stroke lower="{_num(lower)}" upper="{_num(upper)}"/></actuator>'
    )


def _transmissions() -> str:
    cylinders = "".join(
        f"""  <transmission name="{name}">
    <type>redundancy/LinearCylinder</type>
    <joint name="{JOINT_OF[name]}"/>
    {_stroke(name)}
    <attachment link="{PARENT_OF[name]}" xyz="{_point(base)}"/>
    <attachment link="{name}" xyz="{_point(rod)}"/>
  </transmission>
"""
        for name, base, rod in (
            ("boom", BOOM_CYLINDER_BASE, BOOM_CYLINDER_ROD),
            ("stick", STICK_CYLINDER_BASE, STICK_CYLINDER_ROD),
        )
    )
    return f"""{cylinders}  <transmission name="bucket">
    <type>redundancy/LinkageCylinder</type>
    <joint name="bucket_joint"/>
    {_stroke("bucket")}
    <base link="stick" xyz="{_point(BUCKET_CYLINDER_BASE)}"/>
    <rocker link="stick" xyz="{_point(ROCKER_PIVOT)}" length="{_num(ROCKER_LENGTH)}"/>
    <coupler link="bucket" xyz="{_point(COUPLER_PIN)}" length="{_num(COUPLER_LENGTH)}"/>
    <branch value="{BRANCH}"/>
  </transmission>
"""


def _text(limits: dict[str, tuple[float, float]]) -> str:
    tip = TIP_RADIUS * cos(radians(-TIP_ANGLE)), TIP_RADIUS * sin(radians(-TIP_ANGLE))
    return f"""<?xml version="1.0"?>
<!-- A hydraulic excavator's front: boom, stick and a bucket driven through a four-bar linkage.
     Sources of every number: README.md. Generated by excavator/generate.py; edit that, not this. -->
<robot name="excavator">
  <material name="steel"><color rgba="0.95 0.65 0.10 1"/></material>
  <link name="ground">
{_box((0.0, 0.35), 3.0, 0.7, 2.2)}  </link>
  <joint name="chassis_mount" type="fixed">
    <parent link="ground"/>
    <child link="chassis"/>
    <origin xyz="{_xyz(0, 0, SWING_HEIGHT)}"/>
  </joint>
  <link name="chassis">
{_box((-0.6, 0.5), 2.6, 1.0, WIDTH["chassis"])}  </link>
{_joint("boom", limits["boom"])}\
{_link("boom")}\
{_joint("stick", limits["stick"])}\
{_link("stick")}\
{_joint("bucket", limits["bucket"])}\
{_link("bucket")}\
  <joint name="tip_mount" type="fixed">
    <parent link="bucket"/>
    <child link="tip"/>
    <origin xyz="{_point(tip)}"/>
  </joint>
  <link name="tip"/>
{_transmissions()}</robot>
"""


def joint_limits() -> dict[str, tuple[float, float]]:
    """Each joint's range (rad) whose cylinder lengths are the stroke limits, holding the other
    joints at the reference pose: brackets stepped out from the reference, then Brent's method
    on x_i(q_i) − limit, with x from the toolkit on the URDF without joint limits."""
    from redundancy import actuator_space, load_robot

    wide = {name: (-np.pi, np.pi) for name in JOINT_OF}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "excavator.urdf"
        path.write_text(_text(wide))
        robot = load_robot(path)
    reference = np.radians([REFERENCE[name] for name in JOINT_OF])
    limits = {}
    for i, name in enumerate(JOINT_OF):
        row, (lower, upper) = robot.actuators.names.index(name), STROKES[name]

        def length(angle: float, i=i, row=row) -> float:
            q = reference.copy()
            q[i] = angle
            return float(actuator_space(robot, q).x[0, row])

        found = []
        for step in (-radians(1), radians(1)):
            # The length is monotonic over the stroke: step out until it leaves the stroke.
            angle = reference[i]
            while lower <= length(angle + step) <= upper:
                angle += step
            limit = lower if length(angle + step) < lower else upper
            found.append(brentq(lambda a, s=limit: length(a) - s, angle, angle + step, xtol=1e-12))
        limits[name] = (min(found), max(found))
    return limits


def urdf() -> str:
    """The excavator's URDF text."""
    return _text(joint_limits())


HERE = Path(__file__).parent
OUTPUT = HERE / "excavator.urdf"

if __name__ == "__main__":
    OUTPUT.write_text(urdf())
    print(f"wrote {OUTPUT.name}")
