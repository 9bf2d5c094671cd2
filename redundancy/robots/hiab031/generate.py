"""Write ``hiab031.urdf`` from the seed paper's parameters (section 3, Fig. 1), and its slewing
variant ``../hiab031_slewing/hiab031_slewing.urdf`` (the same crane on its slewing column).

Run ``python redundancy/robots/hiab031/generate.py`` after changing a number here; a test checks that the
committed URDFs are exactly what this script writes.

Frame (see DESIGN.md): the task plane is the URDF world x-z plane, world x = y1, world z = y2,
and the world origin is the paper's task origin, so joint 1 sits at (-e, 0, c). Angles count
positive counterclockwise in that plane, i.e. about the world -y axis, which is every revolute
joint's axis. URDF joint values are the paper's joint coordinates q (Eqs. 2-3): at q_i = 0 a boom
points at the constant angle c_i, so theta_i = q_i + c_i. The telescope joint value is d3.

Cylinders (Eq. 9): the lift cylinder runs from a point on the column, L11 from joint 1 at the
angle -90 deg + alpha1, to a point on boom 1, L12 from joint 1 at alpha2 below the boom axis; the
angle between the two points seen from joint 1 is then exactly q1. The fold cylinder runs from a
point on boom 1, L21 from joint 2 at beta1 below the backward boom-1 axis, to a point on boom 2,
L22 from joint 2 at beta2 below its axis; the angle between them is exactly q2.
"""

from math import cos, degrees, pi, radians, sin
from pathlib import Path

# Section 3 of the paper: lengths in m, angles in degrees, masses in kg.
L1, L2, L3 = 1.600, 1.650, 1.470
L11, L12, L21, L22 = 1.037, 0.376, 1.130, 0.310
E, C = 0.228, 0.957
ALPHA1, ALPHA2, BETA1, BETA2 = 21.7, 10.6, 27.1, 2.93
MASS1, MASS2, MASS3 = 80.0, 100.0, 36.0  # rho_i * L_i
THETA1_LIMITS = (-10.3, 92.1)
THETA2_LIMITS = (-137.6, -12.4)
D3_LIMITS = (0.180, 1.270)
X12_STROKE = (0.830, 1.375)
X3_STROKE = (0.0, 1.090)

# Eqs. (2)-(3): theta_i = q_i + c_i.
C1 = -pi / 2 + radians(ALPHA1 + ALPHA2)
C2 = radians(BETA1 + BETA2) - pi

# Not in the paper (assumptions for the slewing variant, see its README): the slewing column's
# mass and radius, and the slewing range of a rack-and-pinion slew, 400 degrees.
SLEWING_COLUMN_MASS, SLEWING_COLUMN_RADIUS = 60.0, 0.10
SLEW_LIMITS = (-200.0, 200.0)

# Not in the paper: actuator force and speed ratings for the URDF <limit> tags (unused by the
# toolkit), and the size of the drawn boxes.
EFFORT, VELOCITY = 1.0e5, 1.0
BOOM_WIDTH, TELESCOPE_WIDTH = 0.14, 0.09


def _num(value: float) -> str:
    return f"{value:.15g}"


def _xyz(*values: float) -> str:
    return " ".join(_num(v) for v in values)


def _in_plane(length: float, angle: float, joint: float = 0.0) -> str:
    """A point at ``length`` from a joint at ``joint`` on the link x axis, ``angle`` rad
    counterclockwise from that axis."""
    return _xyz(joint + length * cos(angle), 0.0, length * sin(angle))


def _rod_link(name: str, mass: float, length: float, width: float, colour: str) -> str:
    """A uniform thin rod along the link x axis from the joint to ``length``."""
    centre = length / 2
    inertia = mass * length**2 / 12  # about the centre, across the rod; ~0 along it
    return f"""  <link name="{name}">
    <inertial>
      <origin xyz="{_xyz(centre, 0, 0)}"/>
      <mass value="{_num(mass)}"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="{_num(inertia)}" iyz="0" izz="{_num(inertia)}"/>
    </inertial>
    <visual>
      <origin xyz="{_xyz(centre, 0, 0)}"/>
      <geometry><box size="{_xyz(length, width, width)}"/></geometry>
      <material name="{colour}"/>
    </visual>
  </link>
"""


def _revolute(name: str, parent: str, child: str, xyz: str, offset: float, limits) -> str:
    lower, upper = (radians(t) - offset for t in limits)
    return f"""  <joint name="{name}" type="revolute">
    <parent link="{parent}"/>
    <child link="{child}"/>
    <origin xyz="{xyz}" rpy="{_xyz(0, -offset, 0)}"/>
    <axis xyz="0 -1 0"/>
    <limit lower="{_num(lower)}" upper="{_num(upper)}" effort="{EFFORT:g}" velocity="{VELOCITY:g}"/>
  </joint>
"""


def _cylinder(name: str, joint: str, base: tuple[str, str], rod: tuple[str, str]) -> str:
    return f"""  <transmission name="{name}">
    <type>redundancy/LinearCylinder</type>
    <joint name="{joint}"/>
    <actuator name="{name}"><stroke lower="{_num(X12_STROKE[0])}" upper="{_num(X12_STROKE[1])}"/></actuator>
    <attachment link="{base[0]}" xyz="{base[1]}"/>
    <attachment link="{rod[0]}" xyz="{rod[1]}"/>
  </transmission>
"""


def _base(slewing: bool) -> str:
    """The fixed base and, for the slewing variant, the slewing column about the world z axis."""
    column = f"""    <visual>
      <origin xyz="{_xyz(-E, 0, C / 2)}"/>
      <geometry><box size="{_xyz(0.2, 0.2, C)}"/></geometry>
      <material name="column"/>
    </visual>
"""
    if not slewing:
        return f'  <link name="base">\n{column}  </link>\n'
    inertia = SLEWING_COLUMN_MASS * SLEWING_COLUMN_RADIUS**2 / 2
    lower, upper = (radians(a) for a in SLEW_LIMITS)
    return f"""  <link name="base">
    <visual>
      <geometry><cylinder radius="0.25" length="0.04"/></geometry>
      <material name="column"/>
    </visual>
  </link>
  <joint name="slew_joint" type="revolute">
    <parent link="base"/>
    <child link="slewing_column"/>
    <axis xyz="0 0 1"/>
    <limit lower="{_num(lower)}" upper="{_num(upper)}" effort="{EFFORT:g}" velocity="{VELOCITY:g}"/>
  </joint>
  <link name="slewing_column">
    <inertial>
      <origin xyz="{_xyz(-E, 0, C / 2)}"/>
      <mass value="{_num(SLEWING_COLUMN_MASS)}"/>
      <inertia ixx="{_num(inertia)}" ixy="0" ixz="0" iyy="{_num(inertia)}" iyz="0" izz="{_num(inertia)}"/>
    </inertial>
{column}  </link>
  <transmission name="slew">
    <type>redundancy/Identity</type>
    <joint name="slew_joint"/>
    <actuator name="slew"><stroke lower="{_num(lower)}" upper="{_num(upper)}"/></actuator>
  </transmission>
"""


def urdf(slewing: bool = False) -> str:
    """The crane's URDF text; ``slewing`` puts it on a slewing column (4 joints)."""
    column_point = _in_plane(L11, C1 - radians(ALPHA2))  # = -90 deg + alpha1 in the world
    boom1_point = _in_plane(L12, -radians(ALPHA2))
    boom1_rear_point = _in_plane(L21, radians(BETA1) - pi, joint=L1)
    boom2_point = _in_plane(L22, -radians(BETA2))
    name = "hiab031_slewing" if slewing else "hiab031"
    return f"""<?xml version="1.0"?>
<!-- HIAB 031 loader crane, from "An improved pseudoinverse solution for redundant hydraulic
     manipulators" (Robotica), section 3. Generated by hiab031/generate.py; edit that, not this. -->
<robot name="{name}">
  <material name="column"><color rgba="0.35 0.35 0.38 1"/></material>
  <material name="boom"><color rgba="0.95 0.65 0.10 1"/></material>
  <material name="telescope"><color rgba="0.85 0.85 0.85 1"/></material>
{_base(slewing)}\
  <joint name="column_mount" type="fixed">
    <parent link="{"slewing_column" if slewing else "base"}"/>
    <child link="column"/>
    <origin xyz="{_xyz(-E, 0, C)}"/>
  </joint>
  <link name="column"/>
{_revolute("boom1_joint", "column", "boom1", _xyz(0, 0, 0), C1, THETA1_LIMITS)}\
{_rod_link("boom1", MASS1, L1, BOOM_WIDTH, "boom")}\
{_revolute("boom2_joint", "boom1", "boom2", _xyz(L1, 0, 0), C2, THETA2_LIMITS)}\
{_rod_link("boom2", MASS2, L2, BOOM_WIDTH, "boom")}\
  <joint name="telescope_joint" type="prismatic">
    <parent link="boom2"/>
    <child link="telescope"/>
    <origin xyz="0 0 0"/>
    <axis xyz="1 0 0"/>
    <limit lower="{_num(D3_LIMITS[0])}" upper="{_num(D3_LIMITS[1])}" effort="{EFFORT:g}" velocity="{VELOCITY:g}"/>
  </joint>
{_rod_link("telescope", MASS3, L3, TELESCOPE_WIDTH, "telescope")}\
  <joint name="tool_mount" type="fixed">
    <parent link="telescope"/>
    <child link="tool"/>
    <origin xyz="{_xyz(L3, 0, 0)}"/>
  </joint>
  <link name="tool"/>
{_cylinder("x1", "boom1_joint", ("column", column_point), ("boom1", boom1_point))}\
{_cylinder("x2", "boom2_joint", ("boom1", boom1_rear_point), ("boom2", boom2_point))}\
  <transmission name="x3">
    <type>redundancy/Prismatic</type>
    <joint name="telescope_joint"/>
    <actuator name="x3"><stroke lower="{_num(X3_STROKE[0])}" upper="{_num(X3_STROKE[1])}"/></actuator>
    <offset value="{_num(L3 - L2)}"/>
  </transmission>
</robot>
"""


HERE = Path(__file__).parent
OUTPUTS = {
    HERE / "hiab031.urdf": False,
    HERE.parent / "hiab031_slewing" / "hiab031_slewing.urdf": True,
}

if __name__ == "__main__":
    for path, slewing in OUTPUTS.items():
        path.write_text(urdf(slewing))
        print(f"wrote {path.name}")
    print(f"c1 = {degrees(C1):.2f} deg, c2 = {degrees(C2):.2f} deg")
