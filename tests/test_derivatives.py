"""Every derivative against central finite differences: J, A, Ȧ, and the robot-independent
point kinematics under them."""

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from joint_space import fk, jacobian
from sampling import random_configurations, random_velocities

from redundancy import actuator_space, bundled_robots, load_robot

STEP = 1e-6


def central_difference(f, q, direction):
    return (f(q + STEP * direction) - f(q - STEP * direction)) / (2 * STEP)


def columns(f, q):
    """∂f/∂q by central differences, one column per joint."""
    return np.stack([central_difference(f, q, e) for e in np.eye(len(q))], axis=-1)


@pytest.fixture(scope="module", params=bundled_robots())
def robot(request):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the Panda declares no actuators
        return load_robot(request.param)


def test_task_jacobian_matches_finite_differences(robot):
    for q in random_configurations(robot, 20, seed=10, margin=0.01):
        np.testing.assert_allclose(
            jacobian(robot, q), columns(lambda qq: fk(robot, qq), q), atol=1e-8
        )


def test_actuator_jacobian_matches_finite_differences(robot):
    for q in random_configurations(robot, 20, seed=11, margin=0.01):

        def x(qq):
            return actuator_space(robot, qq).x[0]

        np.testing.assert_allclose(actuator_space(robot, q).A[0], columns(x, q), atol=1e-8)


def test_actuator_jacobian_rate_matches_finite_differences(robot):
    q = random_configurations(robot, 20, seed=12, margin=0.01)
    v = random_velocities(robot, 20, seed=13)
    space = actuator_space(robot, q, v)
    for qi, vi, A_dot in zip(q, v, space.A_dot):
        expected = central_difference(lambda qq: actuator_space(robot, qq).A[0], qi, vi)
        np.testing.assert_allclose(A_dot, expected, atol=1e-7)


def test_task_jacobian_rate_matches_finite_differences(robot):
    q = random_configurations(robot, 10, seed=14, margin=0.01)
    v = random_velocities(robot, 10, seed=15)
    motion = robot.task(robot.kinematics(q, v))
    for qi, vi, J_dot in zip(q, v, motion.jacobian_rate):
        np.testing.assert_allclose(
            J_dot, central_difference(lambda qq: jacobian(robot, qq), qi, vi), atol=1e-7
        )


def test_rates_read_from_the_pass_equal_pinocchios(robot):
    """The tracked points' velocities and Jacobian rates of the compiled pass
    (`Kinematics.moving`) equal Pinocchio's own Python calls, to rounding."""
    assert_rates_equal_pinocchios(robot)


def test_a_mimic_joints_rates_match_finite_differences():
    """A mimic joint shares its column with the joint it follows, in J and in J̇: every tracked
    point's Jacobian rate (the tool's on the mimic joint among them) and Ȧ are the derivatives
    of the pass's own J_p and A along v. (Pinocchio 4.1's world-aligned J̇ at a point beyond a
    mimic joint misses that joint's share: 1.65 off on the tool here, where |J̇| is 3.3.)"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(Path(__file__).parent / "fixtures" / "intake" / "mimic" / "robot.toml")
    assert any("Mimic" in joint.shortname() for joint in robot.model.joints)
    q = random_configurations(robot, 10, seed=18, margin=0.01)
    v = random_velocities(robot, 10, seed=19)
    moving, space = robot.kinematics(q, v), actuator_space(robot, q, v)
    for i, (qi, vi) in enumerate(zip(q, v)):
        J_dot = central_difference(lambda qq: robot.kinematics(qq[None]).jacobians[0], qi, vi)
        np.testing.assert_allclose(moving.jacobian_rates[i], J_dot, atol=1e-7)
        A_dot = central_difference(lambda qq: actuator_space(robot, qq).A[0], qi, vi)
        np.testing.assert_allclose(space.A_dot[i], A_dot, atol=1e-7)


def assert_rates_equal_pinocchios(robot):
    q = random_configurations(robot, 10, seed=16, margin=0.01)
    v = random_velocities(robot, 10, seed=17)
    moving = robot.kinematics(q).moving(v)
    model, data = robot.model, robot.model.createData()
    for i in range(len(q)):
        pin.computeJointJacobiansTimeVariation(model, data, q[i], v[i])
        for frame, slot in moving.slots.items():
            rate = pin.getFrameJacobianTimeVariation(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
            np.testing.assert_allclose(moving.jacobian_rates[i, slot], rate[:3], atol=1e-12)
            velocity = pin.getFrameVelocity(model, data, frame, pin.LOCAL_WORLD_ALIGNED).linear
            np.testing.assert_allclose(moving.velocities[i, slot], velocity, atol=1e-12)
