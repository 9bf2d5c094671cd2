"""Hydraulic coordinates against their definitions and against Pinocchio's inverse dynamics."""

import numpy as np
import pinocchio as pin
import pytest
from joint_space import gravity, inverse_dynamics, mass
from sampling import random_configurations, random_velocities

from redundancy import (
    InvalidInputError,
    MinVelocityNorm,
    SingularConfigurationError,
    actuator_space,
    load_robot,
)
from redundancy.resolution.state import singular

CRANES = ["hiab031", "hiab031_slewing"]


@pytest.mark.parametrize("name", CRANES)
def test_actuator_forces_match_inverse_dynamics(name):
    """F_H = M_H ẍ + N_H equals A⁻ᵀ RNEA(q, q̇, q̈) with ẋ = A q̇, ẍ = A q̈ + Ȧ q̇."""
    robot = load_robot(name)
    q = random_configurations(robot, 50, seed=20, margin=0.01)
    v = random_velocities(robot, 50, seed=21)
    a = random_velocities(robot, 50, seed=22)
    space = actuator_space(robot, q, v)
    x_ddot = np.einsum("kij,kj->ki", space.A, a) + np.einsum("kij,kj->ki", space.A_dot, v)
    tau = inverse_dynamics(robot, q, v, a)
    expected = np.linalg.solve(np.swapaxes(space.A, 1, 2), tau[:, :, None])[:, :, 0]
    np.testing.assert_allclose(space.forces(x_ddot), expected, rtol=1e-10, atol=1e-6)


@pytest.mark.parametrize("name", CRANES)
def test_hydraulic_mass_matrix_gives_pinocchios_kinetic_energy(name):
    """½ ẋᵀ M_H ẋ equals Pinocchio's kinetic energy at q̇ = A⁻¹ ẋ, with A from finite
    differences of x: a path independent of CRBA and of the actuator Jacobian."""
    robot = load_robot(name)
    for q, x_dot in zip(
        random_configurations(robot, 20, seed=27, margin=0.01), random_velocities(robot, 20, 28)
    ):
        columns = [
            (actuator_space(robot, q + 1e-6 * e).x[0] - actuator_space(robot, q - 1e-6 * e).x[0])
            / 2e-6
            for e in np.eye(robot.n)
        ]
        v = np.linalg.solve(np.array(columns).T, x_dot)
        energy = pin.computeKineticEnergy(robot.model, robot.model.createData(), q, v)
        M_H = actuator_space(robot, q).M_H[0]
        assert 0.5 * x_dot @ M_H @ x_dot == pytest.approx(energy, rel=1e-7)


def test_hydraulic_quantities_follow_their_definitions(crane):
    q = random_configurations(crane, 30, seed=23)
    v = random_velocities(crane, 30, seed=24)
    space = actuator_space(crane, q, v)
    for i in range(len(q)):
        A_inv = np.linalg.inv(space.A[i])
        np.testing.assert_allclose(space.J_H[i], space.J[i] @ A_inv, rtol=1e-12, atol=1e-12)
        M = mass(crane, q[i])
        np.testing.assert_allclose(space.M_H[i], A_inv.T @ M @ A_inv, rtol=1e-10)
        np.testing.assert_allclose(space.x_dot[i], space.A[i] @ v[i], rtol=1e-12)
        # ẏ is the same in joint and actuator coordinates (Eq. 16).
        np.testing.assert_allclose(space.J_H[i] @ space.x_dot[i], space.J[i] @ v[i], atol=1e-12)
    assert np.all(np.linalg.eigvalsh(space.M_H) > 0)


def test_holding_still_takes_the_gravity_forces(crane):
    q = random_configurations(crane, 10, seed=25)
    space = actuator_space(crane, q)
    G = gravity(crane, q)
    expected = np.linalg.solve(np.swapaxes(space.A, 1, 2), G[:, :, None])[:, :, 0]
    np.testing.assert_allclose(space.forces(np.zeros_like(q)), expected, rtol=1e-12)


def test_one_state_is_a_batch_of_one(crane):
    q = random_configurations(crane, 3, seed=26)
    batch = actuator_space(crane, q)
    single = actuator_space(crane, q[1])
    np.testing.assert_allclose(single.M_H[0], batch.M_H[1], rtol=1e-14)
    assert single.J_H.shape == (1, 2, 3)
    # and its rates, accelerations and task velocities may be given as one row (n,) or (m,)
    rates = np.array([0.1, -0.2, 0.05])
    np.testing.assert_array_equal(single.forces(rates), single.forces(rates[None]))
    np.testing.assert_array_equal(single.joint_velocities(rates), single.joint_velocities([rates]))
    law = MinVelocityNorm()
    np.testing.assert_array_equal(
        law.resolve(single, [0.3, 0.1]), law.resolve(single, [[0.3, 0.1]])
    )
    with pytest.raises(InvalidInputError, match=r"x_ddot must be finite numbers of shape \(3, 3\)"):
        batch.forces(rates)  # a row for a batch of three: which state's?


def test_states_taken_or_joined_are_the_states_evaluated_there(crane):
    """Rows taken (indices, repeated, or a mask) and batches joined are, field by field, the
    states evaluated at those q and v; what depends on q alone (J_H, M_H) is carried over,
    equal to what those states derive afresh."""
    q = random_configurations(crane, 9, seed=40, margin=0.01)
    v = random_velocities(crane, 9, seed=41)
    space = actuator_space(crane, q, v)
    assert space.M_H.shape == (9, crane.n, crane.n)  # derived: carried by take and joined
    rows = np.array([7, 2, 2, 0])
    mask = np.arange(9) % 3 == 1
    cases = [
        (space.take(rows), rows),
        (space.take(mask), np.flatnonzero(mask)),
        (type(space).joined([space.take(rows[:2]), space.take(rows[2:])]), rows),
    ]
    for taken, at in cases:
        fresh = actuator_space(crane, q[at], v[at])
        assert {"J_H", "M_H"} <= set(vars(taken))
        for name in ("q", "v", "x", "A", "y", "J", "J_H", "M_H", "x_dot", "A_dot", "N_H"):
            np.testing.assert_array_equal(getattr(taken, name), getattr(fresh, name), err_msg=name)
        for name in ("positions", "jacobians", "velocities", "jacobian_rates"):
            got, expected = getattr(taken.kinematics, name), getattr(fresh.kinematics, name)
            np.testing.assert_array_equal(got, expected, err_msg=name)


def test_a_singular_actuator_jacobian_is_named(crane):
    """At q1 = 0 the lift cylinder's line passes through joint 1: no torque arm."""
    with pytest.raises(
        SingularConfigurationError, match=r"singular at q = \[0.0, 1.0, 0.5\].*'x1'"
    ):
        actuator_space(crane, [0.0, 1.0, 0.5])


def test_singularity_test_matches_the_singular_values():
    """`singular` agrees with σ_min < 1e-9 σ_max from the SVD, on matrices from orthogonal to
    zero, with NaN and near overflow, one at a time and as a batch."""
    rng = np.random.default_rng(3)
    u, _, vt = np.linalg.svd(rng.normal(size=(3, 3)))
    cases = [rng.normal(size=(3, 3)) for _ in range(5)]
    cases += [u @ np.diag([1.0, 1.0, ratio]) @ vt for ratio in (1e-8, 2e-9, 5e-10, 0.0)]
    cases += [np.zeros((3, 3)), np.full((3, 3), 1e300), 1e300 * u, np.full((3, 3), np.nan)]
    expected = []
    for a in cases[:-1]:
        s = np.linalg.svd(a, compute_uv=False)
        expected.append(bool(s[-1] < 1e-9 * s[0] or s[0] == 0))
    expected.append(True)  # not finite
    assert expected == [False] * 7 + [True] * 4 + [False, True]
    assert singular(np.array(cases)).tolist() == expected
    assert [bool(singular(a[None])[0]) for a in cases] == expected
