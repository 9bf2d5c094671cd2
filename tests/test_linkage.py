"""`LinkageCylinder`: x against a numerical solve of the loop closure, A and Ȧ against finite
differences, both assembly branches, and a linkage that cannot close."""

import numpy as np
import pytest
from declarations import actuator_tables, write_actuator_tables, write_transmissions
from lxml import etree
from scipy.optimize import fsolve
from test_derivatives import central_difference, columns

from redundancy import (
    VELOCITY,
    RobotDescriptionError,
    SingularConfigurationError,
    actuator_space,
    load_robot,
)
from redundancy.model.linkage import LinkageCylinder
from redundancy.model.transmissions import read_transmissions
from redundancy.planning.integrate import simulate
from redundancy.planning.tasks import Segment
from redundancy.resolution.state import joined_found

# A slewing arm carrying a stick whose tip joint turns a bucket through a four-bar. The slew's
# axis is oblique to the linkage's, so the linkage's plane turns every way, and the cylinder's
# base lies 0.1 m off that plane (the rocker pivot and coupler pin lie in it, 0.2 m off the arm's
# mid-plane): every term of the loop's derivatives counts.
ROCKER = ("stick", [1.6, 0.2, 0.25], 0.5)
COUPLER = ("bucket", [0.35, 0.2, 0.15], 0.45)
BASE = ("stick", [0.6, 0.3, 0.35])


def urdf(coupler: float = COUPLER[2], branch: int = 1) -> str:
    def link(name: str) -> str:
        return f"""  <link name="{name}"><inertial><origin xyz="0.5 0 0"/><mass value="100"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="10" iyz="0" izz="10"/></inertial></link>\n"""

    def joint(name, parent, child, xyz, axis, lower, upper, driven=True):
        declared = f"""  <transmission name="{name}"><type>redundancy/Identity</type>
    <joint name="{name}"/></transmission>\n"""
        return f"""  <joint name="{name}" type="revolute"><parent link="{parent}"/>
    <child link="{child}"/><origin xyz="{xyz}"/><axis xyz="{axis}"/>
    <limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/></joint>
{declared if driven else ""}"""

    return f"""<robot name="arm">
  <link name="base"/>
{link("carrier")}{link("stick")}{link("bucket")}\
{joint("slew", "base", "carrier", "0 0 0", "0.48 0.6 0.64", -1.5, 1.5)}\
{joint("lift", "carrier", "stick", "0.2 0 0.5", "0 -1 0", -0.8, 0.8)}\
{joint("curl", "stick", "bucket", "2 0 0", "0 -1 0", -2.5, 0.5, driven=False)}\
  <link name="tip"/>
  <joint name="tip_mount" type="fixed"><parent link="bucket"/><child link="tip"/>
    <origin xyz="1.2 0 -0.3"/></joint>
  <transmission name="bucket">
    <type>redundancy/LinkageCylinder</type>
    <joint name="curl"/>
    <actuator name="bucket"><stroke lower="0.5" upper="2.0"/></actuator>
    <base link="{BASE[0]}" xyz="{" ".join(map(str, BASE[1]))}"/>
    <rocker link="{ROCKER[0]}" xyz="{" ".join(map(str, ROCKER[1]))}" length="{ROCKER[2]}"/>
    <coupler link="{COUPLER[0]}" xyz="{" ".join(map(str, COUPLER[1]))}" length="{coupler}"/>
    <branch value="{branch}"/>
  </transmission>
</robot>
"""


def load(tmp_path, **variant):
    path = tmp_path / f"arm_{abs(hash(tuple(variant.items())))}.urdf"
    path.write_text(urdf(**variant))
    return load_robot(path)


@pytest.fixture(scope="module", params=[1, -1], ids=["branch+1", "branch-1"])
def arm(request, tmp_path_factory):
    return load(tmp_path_factory.mktemp("arm"), branch=request.param)


def states(robot, count, seed):
    rng = np.random.default_rng(seed)
    span = robot.upper - robot.lower
    q = robot.lower + span * (0.01 + 0.98 * rng.random((count, robot.n)))
    return q, rng.normal(size=(count, robot.n))


def loop_points(robot, q):
    """World b, R, C and the joint axis n at q (n,), from frames of the robot's own model."""
    import pinocchio as pin

    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, q)

    def world(link, xyz):
        return data.oMf[model.getFrameId(link)].act(np.array(xyz, dtype=float))

    bucket = data.oMi[model.getJointId("curl")]
    return world(*BASE), world(*ROCKER[:2]), world(*COUPLER[:2]), bucket.rotation @ [0, -1, 0]


def solved_pins(robot, q, coupler=COUPLER[2]):
    """The rocker-coupler pin on each side of R → C (left, right), by root-finding on the two
    loop equations |P − R|² = r², |P − C|² = c² in the linkage's plane."""
    _, R, C, n = loop_points(robot, q)
    e1 = (C - R) - ((C - R) @ n) * n
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    r = ROCKER[2]

    def residual(st):
        P = R + st[0] * e1 + st[1] * e2
        return [(P - R) @ (P - R) - r**2, (P - C) @ (P - C) - coupler**2]

    found = {}
    for side in (1, -1):
        st = fsolve(residual, [0.0, side * r], xtol=1e-12)
        assert np.abs(residual(st)).max() < 1e-12
        P = R + st[0] * e1 + st[1] * e2
        found[int(np.sign((P - R) @ e2))] = P
    assert set(found) == {1, -1}
    return found


def test_length_matches_a_numerical_solve_of_the_loop_closure(arm):
    branch = arm.actuators["bucket"].branch
    q, _ = states(arm, 12, seed=1)
    x = actuator_space(arm, q).x[:, arm.actuators.names.index("bucket")]
    for qi, xi in zip(q, x):
        base = loop_points(arm, qi)[0]
        np.testing.assert_allclose(
            xi, np.linalg.norm(solved_pins(arm, qi)[branch] - base), atol=1e-9
        )


def test_the_two_branches_are_the_two_closures_of_one_loop(tmp_path):
    """The +1 branch is the pin on the left of R → C (joint axis towards the viewer), the −1
    branch the other one, and they give different lengths."""
    left, right = load(tmp_path, branch=1), load(tmp_path, branch=-1)
    q, _ = states(left, 6, seed=2)
    x_left, x_right = (actuator_space(r, q).x[:, 2] for r in (left, right))
    assert np.all(np.abs(x_left - x_right) > 1e-3)
    for qi, a, b in zip(q, x_left, x_right):
        base = loop_points(left, qi)[0]
        pins = solved_pins(left, qi)
        np.testing.assert_allclose(
            [a, b], [np.linalg.norm(pins[s] - base) for s in (1, -1)], atol=1e-9
        )


def test_actuator_jacobian_matches_finite_differences(arm):
    q, _ = states(arm, 10, seed=3)
    for qi in q:
        expected = columns(lambda qq: actuator_space(arm, qq).x[0], qi)
        np.testing.assert_allclose(actuator_space(arm, qi).A[0], expected, atol=1e-8)


def test_actuator_jacobian_rate_matches_finite_differences(arm):
    q, v = states(arm, 10, seed=4)
    for qi, vi, A_dot in zip(q, v, actuator_space(arm, q, v).A_dot):
        expected = central_difference(lambda qq: actuator_space(arm, qq).A[0], qi, vi)
        np.testing.assert_allclose(A_dot, expected, atol=1e-7)


def test_the_drawn_linkage_has_the_declared_lengths(arm):
    q, _ = states(arm, 5, seed=5)
    linkage = arm.actuators["bucket"]
    kinematics = arm.kinematics(q)
    bars = linkage.bars(kinematics)
    for name, length in (("rocker", ROCKER[2]), ("coupler", COUPLER[2])):
        a, b = bars[name]
        np.testing.assert_allclose(np.linalg.norm(b - a, axis=1), length, atol=1e-12)
    base, rod = linkage.ends(kinematics)
    x = actuator_space(arm, q).x[:, 2]
    np.testing.assert_allclose(np.linalg.norm(rod - base, axis=1), x, atol=1e-12)


def test_a_linkage_that_cannot_close_is_one_line_naming_it(tmp_path):
    robot = load(tmp_path, coupler=0.2)  # rocker + coupler 0.7 m, pivot to pin up to 0.85 m
    q = np.zeros(3)
    with pytest.raises(SingularConfigurationError) as error:
        actuator_space(robot, q)
    message = str(error.value)
    assert "\n" not in message
    assert "linkage 'bucket' cannot close at q = [0.0, 0.0, 0.0]" in message
    assert "joint 'curl'" in message


@pytest.mark.parametrize("method", ["adaptive", "rk4"])
def test_a_motion_that_drives_the_linkage_past_closing_fails_that_start_alone(tmp_path, method):
    """With a 0.27 m coupler the loop closes for curl below about −1.86 rad and not above: of
    two starts moved alike, the one driven across that edge is frozen and flagged, as at a
    singular A, and the other runs on; nothing raises."""
    robot = load(tmp_path, coupler=0.27)
    q = np.array([[0.3, 0.2, -2.0], [0.3, 0.2, -2.4]])
    start = actuator_space(robot, q)
    with pytest.raises(SingularConfigurationError, match="linkage 'bucket' cannot close"):
        actuator_space(robot, [0.3, 0.2, -1.7])
    y0 = start.y[1]
    segment = Segment("curl", y0, y0 + start.J[0] @ [0.0, 0.0, 0.4], 1.0)
    motion = simulate(robot, VELOCITY.resolver, segment, q, method=method, gain=0.0)
    assert motion.failed.tolist() == [True, False]
    assert not motion.within_limits[0]
    assert np.isfinite(motion.x[0]).all()  # frozen at the last state the loop closed at
    assert motion.q[0, -1, 2] < -1.8 < motion.q[0, 0, 2] + 0.25
    assert motion.q[1, -1, 2] - motion.q[1, 0, 2] > 0.4  # the other ran the whole segment


def test_batches_found_apart_and_joined_are_the_batch_found_at_once(tmp_path):
    """What the core's evaluator finds for two batches, joined (`joined_found`, how the
    integrator gathers the ends of its steps), is what it finds for both as one batch: every
    array, and the refusal of the linkage counted at its state in the whole batch."""
    robot = load(tmp_path, coupler=0.27)
    q = np.array([[0.3, 0.2, -2.0], [0.3, 0.2, -2.4], [0.3, 0.2, -2.2], [0.3, 0.2, -1.7]])
    evaluator = robot.evaluator()
    apart = joined_found(
        [evaluator.evaluate(q[:2], None, True), evaluator.evaluate(q[2:], None, True)]
    )
    whole = evaluator.evaluate(q, None, True)
    assert apart[-1] == whole[-1] and whole[-1][0] == 3  # the last state cannot close
    for ours, theirs in zip(apart[:-1], whole[:-1], strict=True):
        assert (ours is None) == (theirs is None)
        if ours is not None:
            np.testing.assert_array_equal(ours, theirs)


def test_the_declaration_is_written_and_read_back(tmp_path):
    text = urdf(branch=-1)
    declared = read_transmissions(etree.fromstring(text.encode()), "arm.urdf")
    again = read_transmissions(
        etree.fromstring(write_transmissions(text, declared).encode()), "written"
    )
    linkage, copy = (
        next(m for m in maps if isinstance(m, LinkageCylinder)) for maps in (declared, again)
    )
    assert actuator_tables([copy]) == actuator_tables([linkage])
    assert (copy.branch, copy.rocker[2], copy.coupler[0]) == (-1, ROCKER[2], "bucket")


@pytest.mark.parametrize(
    ("old", "new", "said"),
    [
        (
            '<branch value="1"/>',
            '<branch value="2"/>',
            'branch <branch value="2"/> must be one of 1, -1',
        ),
        ('length="0.5"', 'length="-0.5"', "rocker <rocker link="),
        ('<branch value="1"/>', "", "missing <branch> for branch"),
        ('<coupler link="bucket"', '<coupler link="bucke"', "attached to link 'bucke'"),
        ('<base link="stick" xyz="0.6', '<base link="stick" xyz="nan', "base <base link="),
    ],
)
def test_a_bad_declaration_is_one_line_naming_it(tmp_path, old, new, said):
    path = tmp_path / "arm.urdf"
    text = urdf()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(RobotDescriptionError) as error:
        load_robot(path)
    assert said in str(error.value)
    assert "\n" not in str(error.value)


def test_the_excavators_linkage_is_declared_as_well_beside_its_urdf(tmp_path):
    """The bundled excavator's <transmission>s (two cylinders and the bucket's linkage) written
    as [actuators.*] tables beside the same URDF without them give the same x, A and Ȧ."""
    from redundancy.model.loading import bundled_root

    folder = bundled_root() / "excavator"
    urdf = (folder / "excavator.urdf").read_text()
    declared = read_transmissions(etree.fromstring(urdf.encode()), "excavator.urdf")
    tables = write_actuator_tables(declared)
    assert 'rocker = {link = "stick", xyz = [' in tables and "branch = 1.0" in tables
    (tmp_path / "excavator.urdf").write_text(write_transmissions(urdf, []))
    (tmp_path / "robot.toml").write_text(
        'urdf = "excavator.urdf"\ntool_frame = "tip"\ntask_axes = "xz"\n\n' + tables
    )
    beside, bundled = load_robot(tmp_path / "robot.toml"), load_robot("excavator")
    assert isinstance(beside.actuators["bucket"], LinkageCylinder)
    mid = (bundled.lower + bundled.upper) / 2
    q = mid + 0.2 * (bundled.upper - bundled.lower) * np.array([[0.3, -0.5, 0.8], [-0.7, 0.4, 0.1]])
    v = np.array([[0.1, -0.2, 0.3], [0.2, 0.1, -0.4]])
    ours, theirs = actuator_space(beside, q, v), actuator_space(bundled, q, v)
    np.testing.assert_array_equal(ours.x, theirs.x)
    np.testing.assert_array_equal(ours.A, theirs.A)
    np.testing.assert_array_equal(ours.A_dot, theirs.A_dot)
