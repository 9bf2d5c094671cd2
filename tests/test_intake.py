"""Real machines as they come: untouched URDFs with their actuators declared beside them, and
what such URDFs hold (continuous and mimic joints, xacro, missing meshes and inertias, floating
roots, locked joints, tool points), each loaded and run through the study and the playback."""

import contextlib
import re
import shutil
import tomllib
import warnings
from pathlib import Path

import meshcat
import numpy as np
import pytest
import umsgpack
from declarations import actuator_tables, write_actuator_tables, write_transmissions
from joint_space import fk, jacobian, mass
from lxml import etree
from sampling import random_configurations

from redundancy import (
    ActuatorMap,
    InvalidInputError,
    RedundancyError,
    RobotDescriptionError,
    actuator_space,
    default_start,
    improved_start,
    load_robot,
    run_study,
)
from redundancy.cli import _play_motion, main, parser
from redundancy.model.loading import bundled_root
from redundancy.model.parameters import Choice, Number
from redundancy.model.transmissions import read_actuator_tables, read_transmissions
from redundancy.planning.ik import configuration_at, free_configurations
from redundancy.planning.integrate import simulate
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.objectives import VELOCITY
from redundancy.study.check import check
from redundancy.viz.playback import Playback, Recording

FIXTURES = Path(__file__).parent / "fixtures" / "intake"
KINDS = ("continuous", "mimic", "meshes", "massless", "xacro")
CRANE_URDF = bundled_root() / "hiab031" / "hiab031.urdf"


def quietly(path, **options):
    """``load_robot`` with the warnings it gives, for the tests that do not check them."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_robot(path, **options)


def run(argv, capsys):
    """``redundancy ARGV`` in this process: the exit status and stderr's lines, notes aside."""
    try:
        status = main(argv)
    except SystemExit as exit:
        status = exit.code
    lines = capsys.readouterr().err.strip().splitlines()
    return status, [line for line in lines if not line.startswith("redundancy: note:")]


def sidecar(tmp_path, kind="continuous", replace=()):
    """A copy of a fixture robot's folder in ``tmp_path`` with its robot.toml edited by the
    ``replace`` pairs (old, new), and the path of that robot.toml."""
    folder = tmp_path / kind
    folder.mkdir()
    for file in (FIXTURES / kind).iterdir():
        (folder / file.name).write_bytes(file.read_bytes())
    (tmp_path / "task.toml").write_bytes((FIXTURES / "task.toml").read_bytes())
    text = (folder / "robot.toml").read_text()
    for old, new in replace:
        assert old in text, old
        text = text.replace(old, new)
    (folder / "robot.toml").write_text(text)
    return folder / "robot.toml"


# -- one schema, two forms ----------------------------------------------------------------


def test_actuator_tables_and_transmissions_convert_into_each_other(tmp_path, crane):
    """The crane's <transmission>s written as [actuators.*] tables beside the same URDF without
    them load to the same actuators (x and A equal at random states), and written back as
    <transmission>s give the original declarations."""
    declared = read_transmissions(etree.parse(str(CRANE_URDF)).getroot(), "crane")
    bare = write_transmissions(CRANE_URDF.read_text(), [])
    (tmp_path / "crane.urdf").write_text(bare)
    tables = write_actuator_tables(declared)
    (tmp_path / "robot.toml").write_text(
        'urdf = "crane.urdf"\ntool_frame = "tool"\ntask_axes = "xz"\n\n' + tables
    )
    beside = load_robot(tmp_path / "robot.toml")
    q = random_configurations(crane, 20, seed=3)
    ours, theirs = actuator_space(beside, q), actuator_space(crane, q)
    np.testing.assert_array_equal(ours.x, theirs.x)
    np.testing.assert_array_equal(ours.A, theirs.A)
    assert write_transmissions(bare, beside.actuators.maps) == write_transmissions(bare, declared)
    assert tomllib.loads(tables)["actuators"] == actuator_tables(declared)
    assert "[actuators.x1]" in tables and 'base = {link = "column", xyz = [' in tables


class Winch(ActuatorMap):
    """A user's own kind, declared once: a rope drum on a joint, x = radius · q + slack, drawn
    in or paid out (``sense``)."""

    parameters = (
        Number("radius", "drum radius, m"),
        Number("slack", "rope length at q = 0, m", 0.0),
        Choice("sense", "which way the rope runs", "in", choices=("in", "out")),
    )

    def __init__(self, name, joint, lower=-np.inf, upper=np.inf, radius=1.0, slack=0.0, sense="in"):
        super().__init__(name, joint, lower, upper)
        self.radius, self.slack, self.sense = radius, slack, sense

    def evaluate(self, kinematics):
        sign = 1.0 if self.sense == "in" else -1.0
        row = np.zeros_like(kinematics.q)
        row[:, self.index] = sign * self.radius
        return sign * self.radius * kinematics.q[:, self.index] + self.slack, row

    def rate(self, kinematics):
        return np.zeros_like(kinematics.q)


def test_a_users_own_kind_is_declared_in_either_form_from_one_list_of_parameters(tmp_path):
    toml = sidecar(
        tmp_path,
        replace=[
            (
                'kind = "Prismatic"\njoint = "telescope_joint"\nstroke = [0.2, 1.1]\noffset = 0.2',
                "",
            ),
            ("[actuators.x3]", ""),
        ],
    )
    text = toml.read_text().replace("# telescope cylinder", "")
    text += '\n[actuators.rope]\nkind = "Winch"\njoint = "telescope_joint"\nradius = 0.25\n'
    text += 'sense = "out"\nstroke = [-1.0, 1.0]\n'
    toml.write_text(text)
    robot = quietly(toml)
    rope = robot.actuators["rope"]
    assert (rope.radius, rope.slack, rope.sense) == (0.25, 0.0, "out")
    assert actuator_space(robot, (robot.lower + robot.upper) / 2).A[0, 2, 2] == -0.25
    urdf = write_transmissions((toml.parent / "arm.urdf").read_text(), [rope])
    assert '<radius value="0.25"/>' in urdf and '<sense value="out"/>' in urdf
    again = read_transmissions(etree.fromstring(urdf.encode()), "arm")
    assert again[0].declared() == rope.declared()
    tables = read_actuator_tables({"rope": {"kind": "Winch", "joint": "j", "radius": 2}}, "f")
    assert tables[0].declared() == {"radius": 2.0, "slack": 0.0, "sense": "in"}


# -- what real URDFs hold -----------------------------------------------------------------


def test_a_continuous_joint_is_one_coordinate_bounded_where_its_cylinder_keeps_its_stroke():
    robot = quietly(FIXTURES / "continuous" / "robot.toml")
    assert (robot.model.nq, robot.model.nv, robot.name) == (3, 3, "continuous")
    for joint, actuator in ((0, "x1"), (1, "x2")):
        stroke = robot.actuators[actuator]
        q = np.tile((robot.lower + robot.upper) / 2, (2, 1))
        q[:, joint] = robot.lower[joint], robot.upper[joint]
        x = np.sort(actuator_space(robot, q).x[:, joint])
        np.testing.assert_allclose(x, [stroke.lower, stroke.upper], atol=1e-12)


def arm_tool(q, bucket=None):
    """The test arm's tool in the x-z plane, by hand: boom joint at z = 1 m, boom 2 m, the
    telescope's joint 0.7 m along the stick, the tool 0.8 m beyond it (on the mimic arm, a
    0.3 m bucket whose angle mimics the stick's, −0.5 q_stick + 0.2)."""
    boom, stick, telescope = q

    def along(angle):
        return np.array([np.cos(angle), np.sin(angle)])

    tool = np.array([0.0, 1.0]) + 2.0 * along(boom) + (0.7 + telescope + 0.8) * along(boom + stick)
    if bucket is not None:
        tool += 0.3 * along(boom + stick + bucket(stick))
    return tool


def test_a_mimic_joint_moves_with_the_joint_it_follows():
    robot = quietly(FIXTURES / "mimic" / "robot.toml")
    assert robot.n == 3 and robot.joint_names == ["boom_joint", "stick_joint", "telescope_joint"]
    q = random_configurations(robot, 10, seed=5)
    expected = [arm_tool(qi, lambda stick: -0.5 * stick + 0.2) for qi in q]
    np.testing.assert_allclose(fk(robot, q), expected, atol=1e-12)
    h = 1e-6  # the task Jacobian against central differences, the mimic's column included
    for qi in q[:3]:
        numeric = np.stack(
            [(fk(robot, qi + h * e) - fk(robot, qi - h * e)) / (2 * h) for e in np.eye(3)], axis=1
        )
        np.testing.assert_allclose(jacobian(robot, qi), numeric, atol=1e-8)


def test_a_tool_point_on_a_link_and_the_xacro_arm_are_the_arm_itself():
    """The xacro arm (a macro, a property) expands to the continuous one: same joints, tool,
    masses; and the tool point is where the hand-written chain puts it."""
    plain = quietly(FIXTURES / "continuous" / "robot.toml")
    expanded = quietly(FIXTURES / "xacro" / "robot.toml")
    assert expanded.name == "xacro" and expanded.joint_names == plain.joint_names
    q = random_configurations(plain, 10, seed=8)
    np.testing.assert_allclose(fk(plain, q), [arm_tool(qi) for qi in q], atol=1e-12)
    np.testing.assert_allclose(fk(expanded, q), fk(plain, q), atol=1e-12)
    np.testing.assert_allclose(mass(expanded, q), mass(plain, q), atol=1e-9)


def test_locked_joints_hold_their_chosen_values_and_drop_their_actuators(tmp_path):
    toml = sidecar(
        tmp_path,
        replace=[('task_axes = "xz"', 'task_axes = "xz"\nlocked_joints = {stick_joint = -1.4}')],
    )
    with pytest.warns(UserWarning, match="actuators on locked joints are dropped: x2"):
        locked = load_robot(toml)
    assert locked.joint_names == ["boom_joint", "telescope_joint"]
    assert locked.actuators.names == ["x1", "x3"]
    q = np.array([[0.3, 0.5], [0.8, 0.1]])
    np.testing.assert_allclose(fk(locked, q), [arm_tool([b, -1.4, t]) for b, t in q], atol=1e-12)
    toml.write_text(toml.read_text().replace("{stick_joint = -1.4}", '["telescope_joint"]'))
    neutral = quietly(toml)
    np.testing.assert_allclose(fk(neutral, [0.3, -1.0]), arm_tool([0.3, -1.0, 0.0]), atol=1e-12)


def test_a_locked_joint_s_actuator_leaves_the_circuit_with_it(tmp_path):
    """The crane with its telescope locked: x3 is dropped, and its cylinder in [hydraulics] with
    it; the circuit is the two other cylinders' as the full crane declares them."""
    shutil.copytree(bundled_root() / "hiab031", tmp_path / "crane")
    toml = tmp_path / "crane" / "robot.toml"
    locked_telescope = 'task_axes = "xz"\nlocked_joints = ["telescope_joint"]'
    toml.write_text(toml.read_text().replace('task_axes = "xz"', locked_telescope, 1))
    with pytest.warns(UserWarning, match="actuators on locked joints are dropped: x3"):
        locked = load_robot(toml)
    full = load_robot("hiab031")
    assert locked.actuators.names == ["x1", "x2"]
    assert locked.circuit().names == ("x1", "x2")
    for mine, theirs in zip(locked.circuit().cylinders, full.circuit().cylinders[:2]):
        assert mine == theirs


def test_missing_meshes_are_named_once_and_their_links_drawn_as_hulls_through_their_joints():
    with pytest.warns(UserWarning) as said:
        robot = load_robot(FIXTURES / "meshes" / "robot.toml")
    meshes = [str(w.message) for w in said if "meshes not found" in str(w.message)]
    assert len(meshes) == 1
    assert "package://arm_description/meshes/boom.stl, meshes/stick.dae" in meshes[0]
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    segment = cycle.segments[0]
    motion = simulate(
        robot, VELOCITY.resolver, segment, configuration_at(robot, segment.start, {"x3": 0.6})[None]
    )
    recording = Recording()
    vis = meshcat.Visualizer(window=recording)
    playback = Playback(motion)
    playback.draw(vis)
    commands = [umsgpack.unpackb(c) for c in recording.commands]
    poses = {
        c["path"].rsplit("/", 1)[-1]: np.array(c["matrix"], dtype=float).reshape(4, 4).T
        for c in commands
        if c["type"] == "set_transform" and "/links/hulls/" in c["path"]
    }
    # the links without a drawable visual (base; boom and stick, whose meshes are missing) are
    # hulls posed with their links: each link's frame at its joint's origin, turned with it
    q = motion.q[0, 0]
    boom, stick, telescope = q
    joints = [
        np.array([0.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        np.array([2 * np.cos(boom), 0.0, 1 + 2 * np.sin(boom)]),
    ]
    joints.append(
        joints[2] + (0.7 + telescope) * np.array([np.cos(boom + stick), 0, np.sin(boom + stick)])
    )
    tool = arm_tool(q)
    assert sorted(poses) == ["base", "boom", "stick"]
    along = np.array([np.cos(boom + stick), 0.0, np.sin(boom + stick)])
    carried = {  # each link's origin, and the origin of the joint it carries in its own frame
        "base": (joints[0], [0, 0, 1], joints[1]),
        "boom": (joints[1], [2, 0, 0], joints[2]),
        "stick": (joints[2], [0.7, 0, 0], joints[2] + 0.7 * along),
    }
    for link, (origin, local, world) in carried.items():  # world coordinates, below the root
        T = poses[link]
        np.testing.assert_allclose(T[:3, 3], origin, atol=1e-9)
        np.testing.assert_allclose(T[:3, :3] @ local + T[:3, 3], world, atol=1e-9)
    T = poses["stick"]  # the tool, 0.7 + telescope + 0.8 m out along the stick
    np.testing.assert_allclose(
        T[:3, :3] @ [0.7 + telescope + 0.8, 0, 0] + T[:3, 3], [tool[0], 0.0, tool[1]], atol=1e-9
    )


def test_a_mesh_the_loader_cannot_read_is_named_and_its_link_drawn_as_a_hull(tmp_path):
    """A mesh file that is there but holds no mesh the loader reads leaves the playback (and
    the study that writes one) drawing its link as a hull, as a missing one does, with a
    warning that names the file; the other links keep their visuals."""
    folder = tmp_path / "meshes"
    shutil.copytree(FIXTURES / "meshes", folder)
    shutil.copy(FIXTURES / "task.toml", tmp_path)
    (folder / "meshes").mkdir()
    (folder / "meshes" / "stick.dae").write_text("not a mesh")
    with pytest.warns(UserWarning, match="meshes not found") as said:
        robot = load_robot(folder / "robot.toml")
    assert not any("stick.dae" in str(w.message) for w in said)
    segment = WorkCycle.from_toml(robot.task_file, dimension=robot.m).segments[0]
    start = configuration_at(robot, segment.start, {"x3": 0.6})[None]
    motion = simulate(robot, VELOCITY.resolver, segment, start)
    with pytest.warns(UserWarning, match=r"meshes that cannot be read.*meshes/stick\.dae"):
        playback = Playback(motion)
    assert sorted(playback.hulls) == ["base", "boom", "stick"]
    assert playback.visuals is not None and playback.visuals.ngeoms >= 1


def test_a_robot_without_inertias_is_kinematic_only(capsys):
    robot = quietly(FIXTURES / "massless" / "robot.toml")
    assert robot.kinematic_only and robot.massless_links == ["boom", "stick", "telescope"]
    status, errors = run(
        [
            "study",
            "--robot",
            str(FIXTURES / "massless" / "robot.toml"),
            "--objective",
            "energy",
            "--quiet",
            "--out",
            "/nonexistent/x",
        ],
        capsys,
    )
    assert status == 2 and len(errors) == 1, errors
    assert (
        "kinematic only: links boom, stick, telescope have no <inertial> in arm.urdf" in errors[0]
    )


def test_a_kinematic_only_robot_with_a_circuit_names_the_table_in_the_way(tmp_path, capsys):
    """The crane with one massless link keeps its [hydraulics] table, whose load pressures need
    the forces: the study of the velocity objective refused with "use ... the velocity
    objective", the one asked for. The line now names the table as what stands in the way."""
    from redundancy.model.loading import bundled_root

    shutil.copytree(bundled_root() / "hiab031", tmp_path / "crane")
    urdf = tmp_path / "crane" / "hiab031.urdf"
    urdf.write_text(urdf.read_text().replace('<mass value="80"/>', '<mass value="0"/>', 1))
    status, errors = run(
        ["study", "--robot", str(tmp_path / "crane" / "robot.toml"), "--objective", "velocity",
         "--samples", "3", "--cycles", "0", "--quiet", "--out", str(tmp_path / "o")],
        capsys,
    )  # fmt: skip
    assert status == 2 and len(errors) == 1, errors
    assert "(the velocity objective without its [hydraulics] table, play, check)" in errors[0]


def test_a_floating_root_is_refused_with_the_fix_and_loads_once_locked(tmp_path):
    text = (FIXTURES / "continuous" / "arm.urdf").read_text()
    text = text.replace(
        '<robot name="arm">',
        '<robot name="arm">\n  <link name="world"/>\n  <joint name="free" type="floating">'
        '<parent link="world"/><child link="base"/></joint>',
    )
    toml = sidecar(tmp_path)
    (toml.parent / "arm.urdf").write_text(text)
    with pytest.raises(
        RobotDescriptionError, match=r"joint 'free' is floating.*locked_joints = \[\"free\"\]"
    ):
        quietly(toml)
    toml.write_text(
        toml.read_text().replace('task_axes = "xz"', 'task_axes = "xz"\nlocked_joints = ["free"]')
    )
    robot = quietly(toml)
    q = random_configurations(robot, 5, seed=2)
    np.testing.assert_allclose(fk(robot, q), [arm_tool(qi) for qi in q], atol=1e-12)


def test_a_robot_loaded_from_a_path_is_named_after_its_folder_or_file(tmp_path, monkeypatch):
    monkeypatch.chdir(FIXTURES / "xacro")
    assert quietly(Path("robot.toml")).name == "xacro"
    assert quietly(Path("arm.urdf.xacro")).name == "arm"


# -- every fixture through the study and the playback ------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_each_fixture_runs_the_velocity_study_and_the_playback(kind, tmp_path, capsys):
    robot = str(FIXTURES / kind / "robot.toml")
    out = tmp_path / "out"
    status, errors = run(
        [
            "study",
            "--robot",
            robot,
            "--objective",
            "velocity",
            "--samples",
            "10",
            "--quiet",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert status == 0, errors
    assert (out / "report.json").is_file() and (out / "playback_velocity_1-2.html").is_file()
    page = tmp_path / "play.html"
    status, errors = run(["play", "--robot", robot, "--html", str(page)], capsys)
    assert status == 0, errors
    assert page.stat().st_size > 100_000


# -- bad input: one line naming the file, the key or element, the value and the choices ----


BAD = [
    (
        'kind = "Prismatic"',
        'kind = "Telescope"',
        '[actuators.x3] kind = "Telescope" is not an actuator kind; kinds: ',
    ),
    (
        "xyz = [0.5, 0.0, 0.4]}",
        "xyz = [0.5, 0.4]}",
        '[actuators.x1] base = {link = "base", xyz = [0.5, 0.4]} must be {link = ',
    ),
    (
        "stroke = [0.3, 1.3]",
        "stroke = [1.3, 0.3]",
        "[actuators.x1] stroke = [1.3, 0.3] must be [lower, upper]",
    ),
    (
        "offset = 0.2",
        "offset = 0.2\nbore = 80",
        "[actuators.x3]: unknown keys ['bore']; keys: kind, joint, stroke, offset",
    ),
    (
        "offset = 0.2",
        'offset = "a"',
        '[actuators.x3] offset = "a" must be a finite number (x − q, m)',
    ),
    (
        'joint = "stick_joint"',
        'joint = "stik"',
        "joint 'stik', which does not exist; joints: boom_joint, stick_joint, telescope_joint",
    ),
    (
        'rod = {link = "boom", xyz = [0.9, 0.0, -0.2]}\n',
        "",
        "[actuators.x1]: missing key rod (the cylinder's rod point)",
    ),
    (
        'task_axes = "xz"',
        'task_axes = "xz"\nlocked_joints = {telescope_joint = 9.0}',
        "locked_joints telescope_joint = 9 must be within the joint's range",
    ),
    (
        'task_axes = "xz"',
        'task_axes = "xz"\nlocked_joints = {stick_joint = "a"}',
        '[locked_joints] stick_joint = "a" must be a finite number',
    ),
    (
        'tool = {link = "telescope", xyz = [0.8, 0.0, 0.0]}',
        'tool = {link = "nope", xyz = [0.8, 0.0, 0.0]}',
        'tool.link = "nope" is not a link of the URDF; links:',
    ),
    (
        'tool = {link = "telescope", xyz = [0.8, 0.0, 0.0]}',
        'tool = {link = "telescope"}',
        "robot.toml: [tool]: missing key 'xyz'",
    ),
    ('urdf = "arm.urdf"', 'urdf = "arm.urdf.xacro"', 'urdf = "arm.urdf.xacro": no such file'),
]


@pytest.mark.parametrize(("old", "new", "fragment"), BAD, ids=[b[2][:30] for b in BAD])
def test_a_bad_sidecar_is_one_line(tmp_path, capsys, old, new, fragment):
    toml = sidecar(tmp_path, replace=[(old, new)])
    status, errors = run(["describe", "--robot", str(toml)], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert str(toml) in errors[0] or "arm.urdf" in errors[0] or "actuator" in errors[0], errors[0]
    assert fragment in errors[0], errors[0]


def test_braces_in_a_folder_or_an_actuator_name_stay_text_in_the_one_line(tmp_path, capsys):
    """An unknown link is named in one line where the robot's folder or the actuator's name
    holds braces, which the message quotes as written (not as a format field)."""
    braced = tmp_path / "run_{v2}"
    braced.mkdir()
    toml = sidecar(braced, replace=[('tool = {link = "telescope"', 'tool = {link = "nope"')])
    status, errors = run(["describe", "--robot", str(toml)], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "run_{v2}" in errors[0] and 'tool.link = "nope" is not a link of the URDF' in errors[0]
    toml = sidecar(tmp_path, replace=[("[actuators.x1]", '[actuators."x{1}"]')])
    text = toml.read_text().replace('link = "boom"', 'link = "nope"', 1)
    toml.write_text(text)
    status, errors = run(["describe", "--robot", str(toml)], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "actuator 'x{1}' is attached to link 'nope', which does not exist" in errors[0]


def test_a_broken_xacro_is_one_line(tmp_path, capsys):
    toml = sidecar(tmp_path, "xacro")
    xacro = toml.parent / "arm.urdf.xacro"
    xacro.write_text(
        re.sub(r'length="\$\{boom_length\}"', 'length="${boom_lenght}"', xacro.read_text())
    )
    status, errors = run(["describe", "--robot", str(toml)], capsys)
    assert status == 2 and len(errors) == 1, errors
    assert "arm.urdf.xacro: xacro cannot expand it" in errors[0] and "boom_lenght" in errors[0]


# -- redundancy check ------------------------------------------------------------------------


def test_check_passes_a_clean_robot(capsys):
    status, errors = run(["check", "--robot", str(FIXTURES / "continuous" / "robot.toml")], capsys)
    assert status == 0, errors


def test_check_flags_a_stroke_the_joint_range_cannot_reach(tmp_path, capsys):
    """The telescope's x3 = q + 0.2 m over q in [0, 1] m reaches [200, 1200] mm: a stroke of
    [1500, 2000] mm blocks a study; one of [100, 1100] mm is a mismatch that does not."""
    toml = sidecar(tmp_path, replace=[("stroke = [0.2, 1.1]", "stroke = [1.5, 2.0]")])
    status = main(["check", "--robot", str(toml)])
    out = capsys.readouterr().out
    assert status == 2
    assert "reaches [200 mm, 1200 mm], stroke [1500 mm, 2000 mm]: UNREACHABLE" in out
    assert "x3: no value of its stroke is reached over telescope_joint's range" in out
    toml.write_text(toml.read_text().replace("stroke = [1.5, 2.0]", "stroke = [0.1, 1.1]"))
    assert main(["check", "--robot", str(toml)]) == 0
    assert (
        "stroke [100 mm, 1100 mm]: MISMATCH: a stroke end is not reached" in capsys.readouterr().out
    )


def test_check_sweeps_a_range_wider_than_a_turn_as_declared(capsys):
    """The slewing crane's slew joint turns ±200°, its actuator's stroke the same: swept as
    declared, not over one turn (which called the stroke a mismatch)."""
    assert main(["check", "--robot", "hiab031_slewing"]) == 0
    assert "slew_joint         reaches [-200°, 200°], stroke [-200°, 200°]: ok" in (
        capsys.readouterr().out
    )


def test_check_finds_where_a_cylinder_line_passes_through_its_joint_axis(tmp_path):
    """With a stroke admitting every length, the boom joint turns a full turn, and x1's line
    passes through the boom's axis where the base point, the axis and the rod point are in
    line: the boom angle turns the rod point (0.9, −0.2) m onto the base point's direction
    (0.5, −0.6) m from the axis, or its opposite; x1 is then |b| − |r| or |b| + |r|."""
    toml = sidecar(tmp_path, replace=[("stroke = [0.3, 1.3]", "stroke = [0.1, 3.0]")])
    robot = quietly(toml)
    found = check(robot)
    x1 = found.actuators[0]
    base, rod = np.array([0.5, -0.6]), np.array([0.9, -0.2])
    aligned = np.arctan2(base[1], base[0]) - np.arctan2(rod[1], rod[0])
    angles = np.sort(np.angle(np.exp(1j * np.array([aligned, aligned + np.pi]))))
    order = np.argsort(x1.singular)
    np.testing.assert_allclose(np.array(x1.singular)[order], angles, atol=1e-4)
    b, r = np.linalg.norm(base), np.linalg.norm(rod)
    lengths = {round(v, 4) for v in x1.singular_x}
    assert lengths == {round(b + r, 4), round(abs(b - r), 4)}
    assert any("x1: A is singular at boom_joint" in line for line in found.blocking())


def test_check_names_where_a_linkage_cannot_close_and_why_it_is_singular(tmp_path, capsys):
    """The excavator's bucket linkage with a rocker of 0.25 m instead of 0.454 m closes only
    from 63.5° of the bucket joint on, whose range starts at 60.15°: check printed the values
    reached as [∞, ∞] (a numpy warning beside) or ended in the kind's error; it now names the
    range where the linkage cannot close as a problem that blocks a study, and the values
    reached where it closes. Where A is singular on a linkage, it says so of the linkage, not
    of the cylinder's line through the joint axis."""
    from redundancy.model.loading import bundled_root

    source = bundled_root() / "excavator"
    for name in ("robot.toml", "task.toml"):
        (tmp_path / name).write_text((source / name).read_text())
    urdf = (source / "excavator.urdf").read_text()
    (tmp_path / "excavator.urdf").write_text(urdf.replace('length="0.4539"', 'length="0.25"'))
    status = main(["check", "--robot", str(tmp_path / "robot.toml")])
    out, err = capsys.readouterr()
    assert status == 2 and not err, err
    assert "bucket   on bucket_joint       reaches [1087 mm, 1524 mm]" in out
    assert (
        "1 problem blocks a study: bucket: its linkage cannot close for bucket_joint within "
        "[60.15°, 63.5°]" in out
    )
    robot = quietly(tmp_path / "robot.toml")
    bucket = check(robot).actuators[2]
    assert bucket.linkage and "linkage" in bucket.why_singular
    assert not check(robot).actuators[0].linkage


def test_check_refuses_a_segment_the_study_refuses_between_reachable_ends(tmp_path, capsys):
    """An arc from the crane's point 1 to point 2 through (2.25, 4.5) m leaves the crane's
    reach between its ends, which check found reached and called the task "ready for a study";
    the study then refused it. Check now says what the study says, naming the segment and the
    point out of reach, and exits 2; with the arc through (2.25, 1.0) m it is ready."""
    task = tmp_path / "task.toml"
    text = 'held = ["x3"]\nsegments = [{{ from = "1", to = "2", via = "v" }}]\n[points]\n'
    text += "1 = [3.5, -0.5]\n2 = [1.0, -0.5]\nv = [2.25, {height}]\n"
    task.write_text(text.format(height=4.5))
    status = main(["check", "--robot", "hiab031", "--task", str(task)])
    out = capsys.readouterr().out
    assert status == 2
    assert "task points:" in out and "NOT reached" not in out
    assert "cannot follow segment 1-2: its point" in out and "out of reach" in out
    task.write_text(text.format(height=1.0))
    assert main(["check", "--robot", "hiab031", "--task", str(task)]) == 0


def test_check_reaches_a_point_a_grid_of_four_held_joints_passes_between(tmp_path):
    """The Panda holds four joints (2, 4, 6, 7: its last four, the default, leave its shoulder
    a sphere to move the tool on): a grid of 3 values each (81 combinations) reaches neither
    of these points, which the arm reaches with its joints free, inside their ranges; check
    finds them reached, and a point beyond its reach (2 m out) not."""
    from redundancy.planning.ik import FOUND

    (tmp_path / "t.toml").write_text(
        'segments = ["a-b", "b-c"]\nheld = ["panda_joint2", "panda_joint4", "panda_joint6", '
        '"panda_joint7"]\n[points]\na = [0.45, 0.0, 0.55]\nb = [0.5, 0.0, 0.5]\n'
        "c = [2.0, 0.0, 0.5]\n"
    )
    import itertools

    from redundancy.planning.ik import inverse_kinematics
    from redundancy.planning.starts import held_actuators, stroke_box

    robot = quietly("panda")
    cycle = WorkCycle.from_toml(tmp_path / "t.toml", dimension=3)
    held = held_actuators(robot, cycle)
    grid = np.array(list(itertools.product(*(np.linspace(*b, 3) for b in stroke_box(robot, held)))))
    for point in ([0.45, 0.0, 0.55], [0.5, 0.0, 0.5]):  # the grid passes between the solutions
        assert not inverse_kinematics(robot, np.array(point), held, grid).reached.any()
    found = check(robot, cycle)
    by_point = {tuple(np.round(p, 3)): ok for p, ok in zip(found.points, found.reached)}
    assert by_point == {(0.45, 0.0, 0.55): True, (0.5, 0.0, 0.5): True, (2.0, 0.0, 0.5): False}
    free, _ = free_configurations(robot, np.array([0.45, 0.0, 0.55]), 64)
    assert len(free) and np.all((free >= robot.lower) & (free <= robot.upper))
    y = robot.task_point(robot.kinematics(free))[0]
    assert np.abs(y - [0.45, 0.0, 0.55]).max() < FOUND


# -- play --start ----------------------------------------------------------------------------


def test_play_starts_from_the_held_values_given_for_two_held_actuators(tmp_path, capsys):
    """The crane with a one-dimensional task holds two actuators (r = 2): --start sets both,
    and the motion starts with each at its value."""
    (tmp_path / "robot.toml").write_text(
        f'urdf = "{CRANE_URDF}"\ntool_frame = "tool"\ntask_axes = "x"\ntask = "task.toml"\n'
    )
    (tmp_path / "task.toml").write_text(
        'name = "reach"\nspeed = 0.5\nsegments = ["1-2"]\nheld = ["x2", "x3"]\n'
        "[points]\n1 = [2.5]\n2 = [2.0]\n"
    )
    robot = quietly(tmp_path / "robot.toml")
    cycle = WorkCycle.from_toml(robot.task_file, dimension=1)
    argv = ["play", "--robot", str(tmp_path / "robot.toml"), "--start", "x2=1.1,x3=0.5"]
    args = parser().parse_args([*argv, "--html", str(tmp_path / "p.html")])
    motion, label = _play_motion(robot, cycle, cycle.segments[0], VELOCITY, args)
    np.testing.assert_allclose(motion.x[0, 0, 1:], [1.1, 0.5], atol=1e-9)
    # the reach alone is reached with the lift up and down: the label says which start it is
    assert label.startswith("x2 = 1100 mm, x3 = 500 mm, one of 2 start configurations there")
    assert main([*argv, "--html", str(tmp_path / "p.html")]) == 0
    capsys.readouterr()
    status, errors = run([*argv[:-1], "x3=0.5", "--html", str(tmp_path / "p.html")], capsys)
    assert status == 2 and errors == [
        "redundancy: error: --start sets x3; task 'reach' holds ['x2', 'x3']: give each, "
        "--start x2=V,x3=V (m, rad)"
    ]
    status, errors = run([*argv[:-1], "x2=2,x3=0.5", "--html", str(tmp_path / "p.html")], capsys)
    assert status == 2 and errors == [
        "redundancy: error: --start x2=2 is outside the stroke of x2: 2000 mm, stroke [830 mm, "
        "1375 mm]"
    ]
    status, errors = run([*argv[:-1], "x2=1100,x3=0.5", "--html", str(tmp_path / "p.html")], capsys)
    assert status == 2 and errors == [  # a length given in mm, as the strokes are shown
        "redundancy: error: --start x2=1100 is outside the stroke of x2: 1100000 mm, stroke "
        "[830 mm, 1375 mm]; did you give mm? the value is in m"
    ]


def test_a_played_page_says_from_which_start_and_best_takes_the_sweep_it_is_given(tmp_path, capsys):
    """play --best writes a page whose heading, and the line it prints, name the start: the
    best of the fast search's starts, or with --method sweep of the --samples it sweeps."""
    page = tmp_path / "p.html"
    for extra, starts in (([], 14), (["--method", "sweep", "--samples", "20"], 6)):
        assert main(["play", "--segment", "1-2", "--best", *extra, "--html", str(page)]) == 0
        expected = f"velocity objective, best of {starts} starts, x3 = 1090 mm"
        assert f"(segment 1-2, {expected})" in capsys.readouterr().out
        assert f"hiab031: segment 1-2, {expected}" in page.read_text()


def test_an_actuator_on_a_mimic_joint_names_the_joints_that_take_one(tmp_path, capsys):
    toml = sidecar(tmp_path, "mimic")
    toml.write_text(
        toml.read_text() + '\n[actuators.b]\nkind = "Identity"\njoint = "bucket_joint"\n'
    )
    status, errors = run(["describe", "--robot", str(toml)], capsys)
    assert status == 2 and errors == [
        f"redundancy: error: {toml}: [actuators.b]: actuator 'b' drives joint 'bucket_joint', "
        "which mimics another joint; declare the actuator on the joint it follows; joints: "
        "boom_joint, stick_joint, telescope_joint"
    ]


def test_describe_says_a_robot_without_inertias_is_kinematic_only(capsys):
    status = main(["describe", "--robot", str(FIXTURES / "massless" / "robot.toml")])
    out = capsys.readouterr().out
    assert status == 0
    assert "mass: none on links boom, stick, telescope (kinematic only)" in out
    assert "M_H" not in out


def test_a_mimic_joint_following_a_locked_joint_is_locked_where_it_follows(tmp_path):
    toml = sidecar(
        tmp_path,
        "mimic",
        replace=[('task_axes = "xz"', 'task_axes = "xz"\nlocked_joints = {stick_joint = -1.4}')],
    )
    locked = quietly(toml)
    assert locked.joint_names == ["boom_joint", "telescope_joint"]
    q = np.array([[0.3, 0.5], [0.8, 0.1]])
    expected = [arm_tool([b, -1.4, t], lambda stick: -0.5 * stick + 0.2) for b, t in q]
    np.testing.assert_allclose(fk(locked, q), expected, atol=1e-12)


def test_a_task_as_large_as_the_robot_is_refused_in_one_line(tmp_path, capsys):
    """A bare URDF's task is the tool's whole position: m = n = 3 for the arm, nothing to
    resolve; check blocks and the study refuses, each saying how to choose the task axes."""
    task = tmp_path / "t.toml"
    task.write_text(
        'name = "t"\nspeed = 0.5\nsegments = ["1-2"]\n'
        "[points]\n1 = [2.8, 0, -0.2]\n2 = [2.8, 0, 1.2]\n"
    )
    urdf = str(FIXTURES / "continuous" / "arm.urdf")
    assert main(["check", "--robot", urdf, "--task", str(task)]) == 2
    assert "no redundancy to resolve" in capsys.readouterr().out
    status, errors = run(
        ["study", "--robot", urdf, "--task", str(task), "--quiet", "--out", str(tmp_path / "o")],
        capsys,
    )
    assert status == 2 and len(errors) == 1, errors
    assert "give fewer task_axes in a robot.toml that names its URDF" in errors[0]
    arm = quietly(urdf)
    segment = WorkCycle.from_toml(task, dimension=arm.m).segments[0]
    for call in (  # no actuator to hold: the same line, not an IndexError
        lambda: improved_start(arm, segment, VELOCITY, held=[]),
        lambda: default_start(arm, segment, []),
    ):
        with pytest.raises(InvalidInputError, match="no redundancy to resolve"):
            call()


def test_the_study_names_a_cylinder_whose_a_turns_singular_inside_its_stroke(tmp_path):
    """Before any simulation, the study names the joint value and the length at which x1's line
    passes through the boom's axis inside its stroke (J_H = J A⁻¹ is undefined there)."""
    toml = sidecar(tmp_path, replace=[("stroke = [0.3, 1.3]", "stroke = [0.1, 3.0]")])
    robot = quietly(toml)
    expected = check(robot).actuators[0].singular_lines()
    assert len(expected) == 2
    assert all(line.startswith("x1: A is singular at boom_joint = ") for line in expected)
    cycle = WorkCycle.from_toml(robot.task_file, dimension=robot.m)
    # the study may then fail where a motion meets the singularity; it has said where it is
    with pytest.warns(UserWarning) as said, contextlib.suppress(RedundancyError):
        run_study(robot, cycle, (VELOCITY,), samples=4, bound=False, progress=False, cycles=0)
    assert "; ".join(expected) in [str(w.message) for w in said]
