"""The bundled HIAB 031 crane against the paper's closed form (Eqs. 4-5, 9, 14, 30-31)."""

import joint_space
import numpy as np
import pytest
from hiab031_closed_form import (
    actuators,
    gravity,
    mass_matrix_hydraulic,
    tool,
    torque_arms,
)
from joint_space import fk
from sampling import random_configurations

from redundancy import actuator_space, load_robot


@pytest.mark.parametrize("payload", [0.0, 100.0, 350.0])
def test_hydraulic_mass_matrix_matches_eqs_30_31(payload):
    robot = load_robot("hiab031", payload=payload)
    q = random_configurations(robot, 200, seed=1)
    space = actuator_space(robot, q)
    for qi, M_H in zip(q, space.M_H):
        expected = mass_matrix_hydraulic(qi, payload)
        assert np.max(np.abs(M_H - expected)) <= 1e-9 * np.max(np.abs(expected))


def test_forward_kinematics_matches_eqs_4_5(crane):
    q = random_configurations(crane, 200, seed=2)
    y = fk(crane, q)
    np.testing.assert_allclose(y, [tool(qi) for qi in q], rtol=0, atol=1e-12)


def test_actuator_lengths_and_torque_arms_match_eqs_9_14(crane):
    q = random_configurations(crane, 200, seed=3)
    space = actuator_space(crane, q)
    np.testing.assert_allclose(space.x, [actuators(qi) for qi in q], rtol=0, atol=1e-12)
    arms = np.array([torque_arms(qi) for qi in q])
    np.testing.assert_allclose(space.A, arms[:, :, None] * np.eye(3), rtol=0, atol=1e-12)


def test_joint_limits_map_onto_stroke_limits_within_2_mm(crane):
    corners = np.array([crane.lower, crane.upper])
    x = actuator_space(crane, corners).x
    strokes = crane.actuators
    np.testing.assert_allclose(x[0], strokes.lower, atol=2e-3)
    np.testing.assert_allclose(x[1], strokes.upper, atol=2e-3)


@pytest.mark.parametrize("payload", [0.0, 250.0])
def test_gravity_matches_closed_form(payload):
    robot = load_robot("hiab031", payload=payload)
    q = random_configurations(robot, 50, seed=4)
    expected = np.array([gravity(qi, payload) for qi in q])
    np.testing.assert_allclose(joint_space.gravity(robot, q), expected, rtol=1e-10, atol=1e-9)


def test_default_payload_is_the_documented_100_kg(crane):
    assert crane.payload == 100.0
