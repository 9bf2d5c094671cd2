"""The URDF front end: yourdfpy's parse built into Pinocchio's model graph. The model is the one
Pinocchio's own URDF parser builds; a mimic joint may follow a joint on any branch; and what a
URDF (or what it loads) holds is never quoted beyond an excerpt."""

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from joint_space import mechanical_energy
from lxml import etree
from test_intake import quietly, run

from redundancy import RobotDescriptionError, actuator_space, bundled_robots, load_robot
from redundancy.cli import main
from redundancy.model.loading import bundled_root
from redundancy.planning.integrate import rate_on_grid

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


# Three branches from the base: c, on a's branch, mimics b; d mimics a. Built in the file's
# order, a's branch would meet c before b is built; b's branch must come first.
CROSSED = """<robot name="crossed">
  <link name="base"/><link name="A"/><link name="B"/><link name="C"/><link name="D"/>
  <joint name="a" type="revolute"><parent link="base"/><child link="A"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="c" type="revolute"><parent link="A"/><child link="C"/><origin xyz="1 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="b" multiplier="0.5" offset="0.1"/></joint>
  <joint name="b" type="prismatic"><parent link="base"/><child link="B"/>
    <origin xyz="0 0.5 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="d" type="revolute"><parent link="base"/><child link="D"/>
    <origin xyz="0 -0.5 0" rpy="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="a"/></joint>
</robot>
"""


def test_mimic_joints_following_joints_on_each_others_sibling_branches_load(tmp_path):
    """Where a mimic joint on one branch follows a joint on a second, and a mimic joint on a
    third follows one on the first, the branches are built leaders first: every link is where
    yourdfpy's forward kinematics puts it. Where two branches each hold the leader of a mimic
    joint on the other, no model numbers a branch's joints together: one line names them."""
    path = tmp_path / "crossed.urdf"
    path.write_text(CROSSED)
    robot = quietly(path)
    assert sorted(robot.joint_names) == ["a", "b"]
    reference = yourdfpy.URDF.load(str(path), load_meshes=False)
    rng = np.random.default_rng(5)
    for q in rng.uniform(robot.lower, robot.upper, size=(5, robot.n)):
        reference.update_cfg(
            q[[robot.joint_names.index(n) for n in reference.actuated_joint_names]]
        )
        for link, placement in placements(robot.model, q).items():
            np.testing.assert_allclose(placement, reference.get_transform(link), atol=1e-12)
    d_on_b = '<joint name="d" type="revolute"><parent link="B"/>'  # d, on b's branch, mimics a
    path.write_text(
        CROSSED.replace('<joint name="d" type="revolute"><parent link="base"/>', d_on_b)
    )
    with pytest.raises(RobotDescriptionError, match=r"mimic joints 'c', 'd' follow joints on one"):
        quietly(path)


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
            "<mimic joint='stick_joint'> follows 'stick_joint', a joint below it on its branch",
        ),
        (
            '"boom_joint" type="revolute"',
            '"boom_joint" type="screw"',
            "joint 'boom_joint': type='screw' must be one of revolute, continuous, prismatic",
        ),
        ('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', "joint 'a_lamp_joint': <axis xyz="),
        ('<child link="lamp"/>', '<child link="lump"/>', "<child link='lump'> is not a link"),
        (
            '<origin xyz="2 0 0"/>',
            '<origin xyz="2 nan 0"/>',
            'joint \'stick_joint\' <origin xyz="2 nan 0"/> must be xyz="x y z" rpy="r p y"',
        ),
        ('<origin xyz="2 0 0"/>', '<origin xyz="2 0 0 5"/>', '<origin xyz="2 0 0 5"/> must be'),
        (
            '<axis xyz="0 0 1"/>',
            '<axis xyz="0 1"/>',
            "joint 'a_lamp_joint' <axis xyz=\"0 1\"/> must",
        ),
        (
            'lower="-2.5" upper="-0.2"',
            'lower="${-pi}" upper="-0.2"',
            'joint \'stick_joint\' <limit lower="${-pi}" upper="-0.2" effort="1" velocity',
        ),
        (
            'multiplier="0.5"',
            'multiplier="nan"',
            "joint 'a_lamp_joint' <mimic joint=\"boom_joint\"",
        ),
        (
            '<link name="lamp"/>',
            '<link name="lamp"/><link name="boom"/>',
            "given more than once: ['boom']",
        ),
        ('"a_lamp_joint"', '"stick_joint"', "joint names must differ; given more than once"),
        ('<child link="lamp"/>', '<child link="boom"/>', "link 'boom' is the child of 2 joints"),
        (
            '<parent link="telescope"/><child link="left"/>',
            '<child link="left"/>',
            "joint 'b_left_joint': it needs <parent link=",
        ),
        (
            '<mimic joint="boom_joint"',
            '<mimic joint="a_lamp_joint"',
            "follow one another in a circle",
        ),
        (
            '<mimic joint="boom_joint" multiplier="0.5" offset="-0.2"/></joint>',
            '<mimic joint="eye_joint"/></joint><link name="eye"/><joint name="eye_joint" '
            'type="fixed"><parent link="lamp"/><child link="eye"/></joint>',
            "<mimic joint='eye_joint'> follows a fixed joint, 'eye_joint'",
        ),
    ],
    ids=[
        "unknown leader",
        "mimic above its leader",
        "joint type",
        "axis",
        "child",
        "NaN origin",
        "four numbers",
        "two-number axis",
        "xacro leftover",
        "NaN multiplier",
        "link twice",
        "joint twice",
        "child twice",
        "no parent",
        "mimic circle",
        "mimic of a fixed joint",
    ],
)
def test_a_bad_joint_is_one_line_naming_it(tmp_path, capsys, old, new, said):
    assert old in SIBLINGS
    (tmp_path / "b.urdf").write_text(SIBLINGS.replace(old, new, 1))
    status, errors = run(["describe", "--robot", str(tmp_path / "b.urdf")], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "b.urdf: " in errors[0] and said in errors[0], errors[0]


# -- a URDF as it comes: what it may hold that a careful one would not ----------------------


def loaded(tmp_path, text, name="arm.urdf", toml=None):
    """The robot of the URDF ``text`` (with the robot.toml ``toml`` beside it, if given: its
    task xyz, its tool the telescope unless it says)."""
    (tmp_path / name).write_text(text)
    if toml is None:
        return quietly(tmp_path / name)
    tool = "" if "tool" in toml else 'tool_frame = "telescope"\n'
    (tmp_path / "robot.toml").write_text(f'urdf = "{name}"\ntask_axes = "xyz"\n{tool}{toml}')
    return quietly(tmp_path / "robot.toml")


def test_a_mimic_of_a_mimic_follows_its_leaders_leader(tmp_path):
    """A third finger mimicking the right finger (itself mimicking the left, q_r = −q_l + 0.1)
    with multiplier 2 and offset 0.3 is where the composed mimic q = 2 (−q_l + 0.1) + 0.3 =
    −2 q_l + 0.5 of the left finger puts it, at random configurations."""
    finger = (
        '<link name="third"/><joint name="third_joint" type="revolute"><parent link="telescope"/>'
        '<child link="third"/><origin xyz="0.8 0.1 0"/><axis xyz="0 -1 0"/>'
        '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
    )
    chained = SIBLINGS.replace(
        "</robot>",
        finger + '<mimic joint="a_right_joint" multiplier="2" offset="0.3"/></joint></robot>',
    )
    composed = SIBLINGS.replace(
        "</robot>",
        finger + '<mimic joint="b_left_joint" multiplier="-2" offset="0.5"/></joint></robot>',
    )
    (tmp_path / "chained").mkdir()
    (tmp_path / "composed").mkdir()
    robot = loaded(tmp_path / "chained", chained)
    reference = loaded(tmp_path / "composed", composed)
    assert robot.joint_names == reference.joint_names
    for q in np.random.default_rng(5).uniform(robot.lower, robot.upper, size=(5, robot.n)):
        ours, theirs = placements(robot.model, q), placements(reference.model, q)
        angle = -2 * q[3] + 0.5  # the third finger turns about −y by it, from the telescope
        turn = pin.AngleAxis(angle, np.array([0.0, -1.0, 0.0])).matrix()
        np.testing.assert_allclose(ours["third"], theirs["third"], atol=1e-12)
        np.testing.assert_allclose(
            ours["telescope"][:3, :3] @ turn, ours["third"][:3, :3], atol=1e-12
        )


def test_the_power_balance_holds_where_mimic_joints_move_the_actuators(tmp_path):
    """Σ F_i ẋ_i = d/dt (T + V), T = ½ q̇ᵀ M q̇ and V = −m g·c (c the centre of mass), along
    q(t) = q0 + v0 t + ½ a t² over 1 s on the sibling-mimic arm, its lamp given a mass, with
    x1's base on the lamp and x4's rod on the right finger: both ends move by mimic joints, so
    Ȧ beyond them is in N_H of the forces F_H = M_H ẍ + N_H. ẍ (the rate of ẋ = A q̇) and the
    energy's rate are fourth-order differences on an h = 10 ms grid: they agree to h⁴ of the
    peak power on the motion's 1 s scale (1e-10 of it measured; 3e-3 to 0.2 of it off with J̇
    beyond a mimic joint missing that joint's share). x1 and x4 each do over a thousand times
    that work at every sample, so the balance weighs them."""
    lamp = (
        '<link name="lamp"><inertial><mass value="5"/><origin xyz="0.2 0 0"/>'
        '<inertia ixx="0.01" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    )
    robot = loaded(
        tmp_path,
        SIBLINGS.replace('<link name="lamp"/>', lamp),
        toml="""
        [actuators.x1]
        kind = "LinearCylinder"
        joint = "boom_joint"
        base = {link = "lamp", xyz = [0.5, 0, -0.6]}
        rod = {link = "boom", xyz = [0.9, 0, -0.2]}
        [actuators.x2]
        kind = "LinearCylinder"
        joint = "stick_joint"
        base = {link = "boom", xyz = [1, 0, 0.3]}
        rod = {link = "stick", xyz = [-0.35, 0, 0.15]}
        [actuators.x3]
        kind = "Prismatic"
        joint = "telescope_joint"
        [actuators.x4]
        kind = "LinearCylinder"
        joint = "b_left_joint"
        base = {link = "telescope", xyz = [0.3, 0, 0.1]}
        rod = {link = "right", xyz = [0.1, 0, 0]}
        """,
    )
    t = np.linspace(0.0, 1.0, 101)
    v0, a = np.array([0.4, -0.3, 0.2, 0.5]), np.array([0.1, 0.2, -0.1, -0.3])
    q = np.array([0.3, -1.0, 0.4, 0.2]) + np.outer(t, v0) + np.outer(t**2 / 2, a)
    space = actuator_space(robot, q, v0 + np.outer(t, a))
    forces = space.forces(rate_on_grid(space.x_dot[None], t)[0])
    stored = rate_on_grid(mechanical_energy(robot, q, space.v)[None], t)[0]
    work = (forces * space.x_dot)[2:-2]  # inside, where both rates are fourth-order
    tolerance = (t[1] - t[0]) ** 4 * np.abs(work.sum(axis=1)).max()
    assert np.abs(work[:, [0, 3]]).min() > 1e3 * tolerance
    error = np.abs(work.sum(axis=1) - stored[2:-2]).max()
    assert error <= tolerance, error


def test_a_chain_deeper_than_pythons_recursion_loads(tmp_path):
    """600 fixed joints of 1 mm each between two revolute joints and a prismatic one: the tool
    (the deepest link) is 0.6 m further out, on the x axis at q = 0."""
    links = "".join(f'<link name="l{i}"/>' for i in range(600))
    fixed = "".join(
        f'<joint name="f{i}" type="fixed"><parent link="l{i}"/><child link="l{i + 1}"/>'
        '<origin xyz="0.001 0 0"/></joint>'
        for i in range(599)
    )
    moving = (
        '<link name="base"/><link name="a"/><link name="b"/>'
        '<joint name="ja" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        '<joint name="jb" type="revolute"><parent link="a"/><child link="l0"/><axis xyz="0 0 1"/>'
        '<origin xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        '<joint name="jc" type="prismatic"><parent link="l599"/><child link="b"/>'
        '<axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>'
    )
    robot = loaded(tmp_path, f'<robot name="deep">{moving}{links}{fixed}</robot>')
    assert robot.tool_frame == "b" and robot.joint_names == ["ja", "jb", "jc"]
    np.testing.assert_allclose(placements(robot.model, np.zeros(3))["b"][:3, 3], [1.599, 0, 0])


def test_the_default_tool_is_the_link_the_most_joints_move(tmp_path):
    """A link fixed to the base, declared last (as UR arms declare theirs), is not the tool: of
    the deepest links, the fingers at the telescope's end, the last is."""
    mounted = SIBLINGS.replace(
        "</robot>",
        '<link name="mount"/><joint name="mount_joint" type="fixed"><parent link="base"/>'
        '<child link="mount"/></joint></robot>',
    )
    robot = loaded(tmp_path, mounted)
    depth = {f.name: len(robot.model.supports[f.parentJoint]) for f in robot.model.frames}
    assert robot.tool_frame in ("left", "right") and depth[robot.tool_frame] == max(depth.values())


def test_a_tool_point_keeps_its_place_beside_a_link_of_its_name(tmp_path):
    """A link named "tool point" (on the base, 9 m away) does not take the place of the tool
    point robot.toml puts 0.1 m along the telescope."""
    clash = SIBLINGS.replace(
        "</robot>",
        '<link name="tool point"/><joint name="marker" type="fixed"><parent link="base"/>'
        '<child link="tool point"/><origin xyz="9 9 9"/></joint></robot>',
    )
    robot = loaded(tmp_path, clash, toml='tool = {link = "telescope", xyz = [0.1, 0, 0]}')
    q = np.array([0.3, -1.0, 0.5, 0.2])
    tip = placements(robot.model, q)["telescope"] @ np.array([0.1, 0, 0, 1])
    np.testing.assert_allclose(robot.task_point(robot.kinematics(q[None]))[0][0], tip[:3])


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
def test_locked_joints_rest_inside_their_range_and_a_fixed_range_locks(tmp_path):
    """Locked without a value, the stick (range [−2.5, −0.2]) rests at the end nearest 0; a
    boom whose range is one value (lower = upper = 0.4) is locked there, with a warning."""
    robot = loaded(tmp_path, SIBLINGS, toml='locked_joints = ["stick_joint"]')
    explicit = loaded(tmp_path, SIBLINGS, toml="locked_joints = {stick_joint = -0.2}")
    q = np.array([0.3, 0.5, 0.2])
    np.testing.assert_allclose(
        placements(robot.model, q)["telescope"], placements(explicit.model, q)["telescope"]
    )
    (tmp_path / "stuck.urdf").write_text(
        SIBLINGS.replace('lower="-1" upper="1.2"', 'lower="0.4" upper="0.4"')
    )
    with pytest.warns(UserWarning, match=r"locked there: boom_joint = 0\.4"):
        stuck = load_robot(tmp_path / "stuck.urdf")
    assert stuck.joint_names == ["stick_joint", "telescope_joint", "b_left_joint"]
    at = loaded(tmp_path, SIBLINGS, toml="locked_joints = {boom_joint = 0.4}")
    q = np.array([-1.0, 0.5, 0.2])
    np.testing.assert_allclose(placements(stuck.model, q)["left"], placements(at.model, q)["left"])


def test_a_revolute_joint_limited_to_1e16_is_sought_within_a_turn(tmp_path):
    """The "no limit" of a revolute joint some exporters write (±1e16 rad): its seeds span the
    turn [−π, π], and inverse kinematics reaches the points it reaches with a range of ±π."""
    from redundancy.planning.ik import inverse_kinematics

    wide = loaded(
        tmp_path, SIBLINGS.replace('lower="-1" upper="1.2"', 'lower="-1e16" upper="1e16"')
    )
    (tmp_path / "turn").mkdir()
    turn = loaded(
        tmp_path / "turn",
        SIBLINGS.replace('lower="-1" upper="1.2"', 'lower="-3.14159" upper="3.14159"'),
    )
    np.testing.assert_allclose([s[0] for s in wide.span], [-np.pi, np.pi])
    q = np.array([[0.5, -1.0, 0.4, 0.1], [-2.0, -2.0, 0.8, 0.0], [2.5, -0.5, 0.1, 0.0]])
    points = turn.task_point(turn.kinematics(q))[0]
    for point, held in zip(points, q[:, 2]):
        solved = inverse_kinematics(wide, point, ["telescope_joint"], [[held]])
        assert solved.reached[0] and solved.miss[0] < 1e-6, solved


def test_odd_but_valid_choices_load(tmp_path):
    """A tiny negative principal moment (a file's rounding) loads as 0; a continuous joint
    locks at any angle (4.9 rad, past a turn: where 4.9 − 2π puts it); a robot's folder, and a
    URDF whose suffix is upper case, load as their robot.toml and URDF."""
    rounded = SIBLINGS.replace('ixx="2" iyy="70"', 'ixx="-1e-9" iyy="70"')
    robot = loaded(tmp_path, rounded)
    np.testing.assert_allclose(robot.model.inertias[1].inertia, np.diag([0.0, 70, 70]), atol=0)
    spun = SIBLINGS.replace(
        '"stick_joint" type="revolute"', '"stick_joint" type="continuous"'
    ).replace('lower="-2.5" upper="-0.2" effort="1" velocity="1"', 'effort="1" velocity="1"')
    turned = loaded(tmp_path, spun, toml="locked_joints = {stick_joint = 4.9}")
    back = loaded(tmp_path, spun, toml=f"locked_joints = {{stick_joint = {4.9 - 2 * np.pi!r}}}")
    q = np.array([0.3, 0.5, 0.2])
    np.testing.assert_allclose(
        placements(turned.model, q)["telescope"], placements(back.model, q)["telescope"], atol=1e-12
    )
    assert quietly(tmp_path).joint_names == back.joint_names
    (tmp_path / "ARM.URDF").write_text(SIBLINGS)
    assert quietly(tmp_path / "ARM.URDF").name == "ARM"


def test_an_actuator_on_a_fixed_joint_says_it_is_fixed(tmp_path, capsys):
    eye = SIBLINGS.replace(
        "</robot>",
        '<link name="eye"/><joint name="eye_joint" type="fixed"><parent link="lamp"/>'
        '<child link="eye"/></joint></robot>',
    )
    (tmp_path / "arm.urdf").write_text(eye)
    (tmp_path / "robot.toml").write_text(
        'urdf = "arm.urdf"\ntool_frame = "telescope"\ntask_axes = "xyz"\n'
        '[actuators.x9]\nkind = "Identity"\njoint = "eye_joint"\n'
    )
    status, errors = run(["describe", "--robot", str(tmp_path / "robot.toml")], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "actuator 'x9' drives joint 'eye_joint', which is fixed (or locked)" in errors[0]


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


def test_a_cylinder_whose_points_its_joint_does_not_move_apart_names_their_links(tmp_path, capsys):
    """Both points of the boom cylinder on the column: the boom joint moves neither, and the
    message says so, not that a point lies on the joint's axis."""
    text = (CRANE / "hiab031.urdf").read_text()
    rod = '<attachment link="column" xyz="0.4 0 -0.5"/>'
    (tmp_path / "crane.urdf").write_text(text.replace(ROD, rod))
    status, errors = run(["describe", "--robot", str(tmp_path / "crane.urdf")], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "x1 cannot move boom1_joint" in errors[0]
    assert "its points lie on 'column', which boom1_joint does not move one against" in errors[0]


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
def test_a_mesh_that_is_no_mesh_is_drawn_as_a_hull_and_named(tmp_path, capsys, mesh):
    """The meshes fixture with files where its meshes are named, which no mesh loader reads:
    the playback, the one place meshes load, is written with those links drawn as hulls, and
    one note names both files and nothing of what they hold."""
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
    status = main(argv)
    said = capsys.readouterr().err.splitlines()
    assert status == 0 and all(line.startswith("redundancy: note:") for line in said), said
    (note,) = (line for line in said if "meshes that cannot be read" in line)
    assert "arm_description/meshes/boom.stl" in note and "meshes/stick.dae" in note
    assert "rest-of-the-secret" not in note and "65534" not in note, note
    assert (tmp_path / "p.html").is_file()
