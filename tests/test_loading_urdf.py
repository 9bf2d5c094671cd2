"""The URDF front end: yourdfpy's parse built into Pinocchio's model graph. The model is the one
Pinocchio's own URDF parser builds; a mimic joint may follow a joint on any branch; and what a
URDF (or what it loads) holds is never quoted beyond an excerpt."""

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from lxml import etree
from test_intake import quietly, run

from redundancy import RobotDescriptionError, bundled_robots, load_robot
from redundancy.model.loading import bundled_root

CRANE = bundled_root() / "hiab031"

# An arm (boom, stick, telescope: the task chain) carrying a gripper and a lamp. The right
# finger mimics the left one, on a sibling branch; the lamp, on the base, mimics the boom. Each
# mimic joint's name sorts before its leader's, so a parser that walks the joints in the order
# of their names meets the mimic joint first.
SIBLINGS = """<robot name="siblings">
  <link name="base"/>
  <link name="boom"><inertial><mass value="200"/><origin xyz="1 0 0"/>
    <inertia ixx="2" iyy="70" izz="70" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="stick"><inertial><mass value="100"/><origin xyz="0.75 0 0"/>
    <inertia ixx="1" iyy="20" izz="20" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="telescope"><inertial><mass value="60"/><origin xyz="0.4 0 0" rpy="0 0.3 0"/>
    <inertia ixx="1" iyy="3" izz="3" ixy="0" ixz="0.1" iyz="0"/></inertial></link>
  <link name="left"><inertial><mass value="2"/><origin xyz="0.1 0 0"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="right"><inertial><mass value="2"/><origin xyz="0.1 0 0"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="lamp"/>
  <joint name="boom_joint" type="revolute"><parent link="base"/><child link="boom"/>
    <origin xyz="0 0 1"/><axis xyz="0 -1 0"/>
    <limit lower="-1" upper="1.2" effort="1" velocity="1"/></joint>
  <joint name="stick_joint" type="revolute"><parent link="boom"/><child link="stick"/>
    <origin xyz="2 0 0"/><axis xyz="0 -1 0"/>
    <limit lower="-2.5" upper="-0.2" effort="1" velocity="1"/></joint>
  <joint name="telescope_joint" type="prismatic"><parent link="stick"/><child link="telescope"/>
    <origin xyz="0.7 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="a_right_joint" type="revolute"><parent link="telescope"/><child link="right"/>
    <origin xyz="0.8 0 -0.05"/><axis xyz="0 -1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="b_left_joint" multiplier="-1" offset="0.1"/></joint>
  <joint name="b_left_joint" type="revolute"><parent link="telescope"/><child link="left"/>
    <origin xyz="0.8 0 0.05"/><axis xyz="0 -1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="a_lamp_joint" type="revolute"><parent link="base"/><child link="lamp"/>
    <origin xyz="0 0.2 1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
    <mimic joint="boom_joint" multiplier="0.5" offset="-0.2"/></joint>
</robot>
"""


def placements(model, q):
    """Every link's world placement (4 × 4) at ``q``, by name."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return {
        frame.name: data.oMf[i].homogeneous
        for i, frame in enumerate(model.frames)
        if frame.type == pin.FrameType.BODY
    }


def test_a_mimic_joint_on_another_branch_loads_and_follows_its_leader(tmp_path):
    """Every link of the sibling-mimic arm is where yourdfpy's own forward kinematics puts it
    (mimic joints applied by yourdfpy), at random configurations; Pinocchio's URDF parser
    refuses the same file."""
    path = tmp_path / "siblings.urdf"
    path.write_text(SIBLINGS)
    with pytest.raises(ValueError, match="mimic"):
        pin.buildModelFromUrdf(str(path), mimic=True)
    robot = quietly(path)
    assert robot.joint_names == ["boom_joint", "stick_joint", "telescope_joint", "b_left_joint"]
    reference = yourdfpy.URDF.load(str(path), load_meshes=False)
    assert reference.actuated_joint_names == robot.joint_names
    rng = np.random.default_rng(4)
    for q in rng.uniform(robot.lower, robot.upper, size=(5, robot.n)):
        reference.update_cfg(q)
        for link, placement in placements(robot.model, q).items():
            np.testing.assert_allclose(placement, reference.get_transform(link), atol=1e-12)
    lamp = placements(robot.model, np.array([0.6, -1.0, 0.5, 0.3]))["lamp"]
    angle = 0.5 * 0.6 - 0.2  # the lamp turns about world z by 0.5 q_boom − 0.2
    np.testing.assert_allclose(lamp[:2, 0], [np.cos(angle), np.sin(angle)], atol=1e-12)


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
@pytest.mark.parametrize("name", bundled_robots())
def test_each_bundled_robots_model_is_pinocchios_own(name):
    """The model built from yourdfpy's parse has the joints, limits, link placements and mass
    matrix of the one Pinocchio's URDF parser builds from the same file (no bundled robot has
    a continuous joint or a mimic joint on another branch)."""
    robot = load_robot(name, payload=0.0)
    own = pin.buildModelFromXML(robot.description, mimic=True)
    locked = [j for j in own.names[1:] if j not in robot.model.names]
    own = pin.buildReducedModel(own, [own.getJointId(j) for j in locked], pin.neutral(own))
    assert list(own.names) == list(robot.model.names)
    np.testing.assert_array_equal(own.lowerPositionLimit, robot.model.lowerPositionLimit)
    np.testing.assert_array_equal(own.upperPositionLimit, robot.model.upperPositionLimit)
    rng = np.random.default_rng(7)
    for q in rng.uniform(robot.lower, robot.upper, size=(4, robot.n)):
        ours, theirs = placements(robot.model, q), placements(own, q)
        for link, placement in theirs.items():
            np.testing.assert_allclose(ours[link], placement, atol=1e-12)
        mass = pin.crba(own, own.createData(), q)
        np.testing.assert_allclose(robot.mass_matrices(q[None])[0], mass, atol=1e-9)


@pytest.mark.parametrize(
    ("old", "new", "said"),
    [
        (
            '<mimic joint="boom_joint"',
            '<mimic joint="nope"',
            "joint 'a_lamp_joint': <mimic joint='nope'> follows no joint of the URDF",
        ),
        (
            '<child link="boom"/>',
            '<child link="boom"/><mimic joint="stick_joint"/>',
            "not a valid URDF: Graph - The parent joint of the mimic node is not in the kinematic",
        ),
        (
            '"boom_joint" type="revolute"',
            '"boom_joint" type="screw"',
            "joint 'boom_joint': type='screw' must be one of revolute, continuous, prismatic",
        ),
        ('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', "joint 'a_lamp_joint': <axis xyz="),
        ('<child link="lamp"/>', '<child link="lump"/>', "<child link='lump'> is not a link"),
    ],
    ids=["unknown leader", "mimic above its leader", "joint type", "axis", "child"],
)
def test_a_bad_joint_is_one_line_naming_it(tmp_path, capsys, old, new, said):
    assert old in SIBLINGS
    (tmp_path / "b.urdf").write_text(SIBLINGS.replace(old, new, 1))
    status, errors = run(["describe", "--robot", str(tmp_path / "b.urdf")], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "b.urdf: " in errors[0] and said in errors[0], errors[0]


# -- a cylinder on its joint's axis: one line naming it and its table -----------------------

ROD = '<attachment link="boom1" xyz="0.369583691280232 0 -0.0691657078303828"/>'
BASE = '<attachment link="column" xyz="0.383427387292961 0 -0.963510476680816"/>'


def boom_axis_origin():
    """Where the boom joint's axis passes, in the column's frame (the joint's origin)."""
    root = etree.parse(str(CRANE / "hiab031.urdf")).getroot()
    return root.find("joint[@name='boom1_joint']/origin").get("xyz")


@pytest.mark.parametrize(
    ("old", "new"),
    [
        *[
            (ROD, f'<attachment link="boom1" xyz="{d} 0 0"/>')
            for d in ("0", "1e-9", "1e-6", "1e-3")
        ],
        (BASE, f'<attachment link="column" xyz="{boom_axis_origin()}"/>'),
    ],
    ids=["rod on the axis", "rod 1e-9 m off", "rod 1e-6 m off", "rod 1e-3 m off", "base on it"],
)
def test_a_cylinder_on_its_joints_axis_is_one_line_naming_it(tmp_path, capsys, old, new):
    text = (CRANE / "hiab031.urdf").read_text()
    assert old in text
    (tmp_path / "crane.urdf").write_text(text.replace(old, new))
    status, errors = run(["describe", "--robot", str(tmp_path / "crane.urdf")], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "crane.urdf: <transmission name='x1'>: x1 cannot move boom1_joint" in errors[0]
    assert "attach each at least 10 mm off it" in errors[0]


def test_a_cylinder_table_on_its_joints_axis_names_the_table(tmp_path):
    """(The table gives no stroke: a cylinder's is unbounded by default, as a transmission's.)"""
    (tmp_path / "robot.toml").write_text(
        f'urdf = "{CRANE / "hiab031.urdf"}"\ntool_frame = "tool"\ntask_axes = "xz"\n'
        '[actuators.x1]\nkind = "LinearCylinder"\njoint = "boom1_joint"\n'
        'base = {link = "column", xyz = [0.38, 0.0, -0.96]}\n'
        'rod = {link = "boom1", xyz = [0.0, 0.0, 0.0]}\n'
    )
    text = (CRANE / "hiab031.urdf").read_text()
    bare = re.sub(r'\s*<transmission name="x1">.*?</transmission>', "", text, flags=re.S)
    (tmp_path / "crane.urdf").write_text(bare)
    toml = (tmp_path / "robot.toml").read_text().replace(str(CRANE / "hiab031.urdf"), "crane.urdf")
    (tmp_path / "robot.toml").write_text(toml)
    with pytest.raises(RobotDescriptionError, match=r"robot.toml: \[actuators.x1\]: x1 cannot"):
        quietly(tmp_path / "robot.toml")


# -- what a URDF loads is never quoted beyond an excerpt -------------------------------------

SECRET = "root:x:0:0:root:/root:/bin/bash\nnobody:x:65534:65534:the-rest-of-the-secret-line\n"


@pytest.mark.parametrize(
    ("content", "use", "fragment"),
    [
        ("a: 1\nkey: value: the-rest-of-the-secret-line\n", "${p['a']}", "line 2: not YAML"),
        (SECRET, "${p}", "it must have one root link"),
    ],
    ids=["not YAML", "a system file as a link's name"],
)
def test_a_xacro_loading_a_system_file_names_it_without_quoting_it(
    tmp_path, capsys, content, use, fragment
):
    (tmp_path / "loaded.yaml").write_text(content)
    (tmp_path / "arm.urdf.xacro").write_text(
        '<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        '  <xacro:property name="p" value="${xacro.load_yaml(\'loaded.yaml\')}" '
        'lazy_eval="false"/>\n'
        f'  <link name="base"/><link name="{use}"/>\n</robot>\n'
    )
    status, errors = run(["describe", "--robot", str(tmp_path / "arm.urdf.xacro")], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert fragment in errors[0], errors[0]
    assert "rest-of-the-secret" not in errors[0] and "65534" not in errors[0], errors[0]


@pytest.mark.parametrize("mesh", ["garbage", "system file"])
def test_a_mesh_that_is_no_mesh_is_one_line(tmp_path, capsys, mesh):
    """The meshes fixture with files where its meshes are named: the playback, the one place
    meshes load, says in one line which file it cannot load."""
    fixtures = Path(__file__).parent / "fixtures" / "intake"
    folder = tmp_path / "meshes"
    folder.mkdir()
    for file in (fixtures / "meshes").iterdir():
        (folder / file.name).write_bytes(file.read_bytes())
    (tmp_path / "task.toml").write_bytes((fixtures / "task.toml").read_bytes())
    content = bytes(np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8))
    if mesh == "system file":
        content = SECRET.encode() * 20
    for name in ("arm_description/meshes/boom.stl", "meshes/stick.dae"):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(content)
    argv = ["play", "--robot", str(folder / "robot.toml"), "--html", str(tmp_path / "p.html")]
    status, errors = run(argv, capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "arm.urdf: cannot load its visual geometry: Could not load resource" in errors[0]
