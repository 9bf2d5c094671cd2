"""Resolution laws against their defining equations on every bundled robot, through both the
batch `resolve` and the one-state `step`: J_H ẋ = ẏ, weighted minimality against a direct solve
of the equality-constrained least-squares problem, and a null-space term that leaves the task."""

import dataclasses
import shutil
import warnings

import numpy as np
import pytest
from sampling import random_configurations

import redundancy.resolution.laws as laws
from redundancy import (
    WorkCycle,
    actuator_space,
    bundled_robots,
    default_start,
    load_robot,
    simulate,
)
from redundancy.model.loading import bundled_root
from redundancy.resolution.laws import GradientProjection, MinKineticEnergy, MinVelocityNorm

RESOLVERS = [MinVelocityNorm(), MinKineticEnergy(), GradientProjection(gain=2.0)]


@pytest.fixture(scope="module", params=bundled_robots())
def robot(request):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the Panda declares no actuators
        return load_robot(request.param)


@pytest.fixture(scope="module")
def states(robot):
    q = random_configurations(robot, 30, seed=30, margin=0.02)
    y_dot = np.random.default_rng(31).normal(scale=0.5, size=(30, robot.m))
    return actuator_space(robot, q), y_dot


def both_ways(resolver, robot, space, y_dot):
    """ẋ by `resolve` on the batch and by `step` one state at a time: (2, k, n)."""
    batch = resolver.resolve(space, y_dot)
    steps = np.array([resolver.step(robot, q, y).x_dot for q, y in zip(space.q, y_dot)])
    return batch, steps


def constrained_least_squares(W, J_H, y_dot, z):
    """argmin (ẋ − z)ᵀ W (ẋ − z) subject to J_H ẋ = ẏ, by its KKT system, one state."""
    n, m = W.shape[0], J_H.shape[0]
    kkt = np.block([[2 * W, J_H.T], [J_H, np.zeros((m, m))]])
    return np.linalg.solve(kkt, np.concatenate([2 * W @ z, y_dot]))[:n]


@pytest.mark.parametrize("resolver", RESOLVERS, ids=lambda r: type(r).__name__)
def test_every_law_tracks_the_task_velocity_both_ways(robot, states, resolver):
    space, y_dot = states
    for x_dot in both_ways(resolver, robot, space, y_dot):
        np.testing.assert_allclose(
            np.einsum("kij,kj->ki", space.J_H, x_dot), y_dot, rtol=1e-9, atol=1e-10
        )


@pytest.mark.parametrize("resolver", RESOLVERS, ids=lambda r: type(r).__name__)
def test_every_law_is_the_weighted_least_squares_solution_both_ways(robot, states, resolver):
    """ẋ minimises (ẋ − z)ᵀ W (ẋ − z) over J_H ẋ = ẏ: z = 0 for the pseudoinverses (weighted
    minimality), z the gradient for gradient projection."""
    space, y_dot = states
    W = resolver.weight(space)
    W = np.broadcast_to(np.eye(robot.n), space.A.shape) if W is None else W
    z = resolver.null_space(space)
    z = np.zeros_like(space.x) if z is None else z
    expected = np.array([constrained_least_squares(*args) for args in zip(W, space.J_H, y_dot, z)])
    scale = np.abs(expected).max()
    for x_dot in both_ways(resolver, robot, space, y_dot):
        np.testing.assert_allclose(x_dot, expected, atol=1e-9 * scale)


def test_step_gives_the_joint_velocities_and_the_task_point(robot, states):
    space, y_dot = states
    step = MinVelocityNorm().step(robot, space.q[0], y_dot[0])
    np.testing.assert_allclose(space.A[0] @ step.q_dot, step.x_dot, atol=1e-12)
    np.testing.assert_allclose(step.y, space.y[0], atol=1e-15)


def test_min_energy_solution_is_not_the_unweighted_one(crane):
    space = actuator_space(crane, random_configurations(crane, 10, seed=33, margin=0.05))
    y_dot = np.random.default_rng(34).normal(scale=0.5, size=(10, crane.m))
    difference = MinKineticEnergy().resolve(space, y_dot) - MinVelocityNorm().resolve(space, y_dot)
    assert np.max(np.abs(difference)) > 1e-3  # the weighting matters on the crane


def test_gradient_projection_adds_only_null_space_motion(robot, states):
    space, y_dot = states
    extra = GradientProjection(gain=2.0).resolve(space, y_dot) - MinVelocityNorm().resolve(
        space, y_dot
    )
    assert np.max(np.abs(extra)) > 1e-4  # it does move the redundant coordinates
    np.testing.assert_allclose(np.einsum("kij,kj->ki", space.J_H, extra), 0, atol=1e-11)


def test_gradient_projection_pushes_actuators_towards_mid_stroke(crane):
    space = actuator_space(crane, random_configurations(crane, 40, seed=30, margin=0.02))
    x_dot = GradientProjection(gain=2.0).resolve(space, np.zeros((40, crane.m)))
    middle = (crane.actuators.lower + crane.actuators.upper) / 2
    span = crane.actuators.upper - crane.actuators.lower
    # Φ grows along the motion: ∇Φ · ẋ ≥ 0 with ∇Φ = −(x − x̄)/Δx².
    growth = np.sum(-(space.x - middle) / span**2 * x_dot, axis=1)
    assert np.all(growth >= -1e-15)


@pytest.mark.parametrize("resolver", RESOLVERS[:2], ids=lambda r: type(r).__name__)
def test_damping_is_the_same_both_ways_where_it_is_due(crane, monkeypatch, resolver):
    """With the singularity threshold raised until every state counts as near singular, both
    ways take the damped branch, which changes the answer, and still agree."""
    q = random_configurations(crane, 20, seed=42, margin=0.05)
    y_dot = np.random.default_rng(43).normal(scale=0.5, size=(20, crane.m))
    space = actuator_space(crane, q)
    undamped = resolver.resolve(space, y_dot)
    monkeypatch.setattr(laws, "SINGULAR_RATIO", 1.0)
    batch, steps = both_ways(resolver, crane, actuator_space(crane, q), y_dot)
    assert np.abs(batch - undamped).max() > 1e-3 * np.abs(undamped).max()
    np.testing.assert_allclose(steps, batch, atol=1e-12)


@pytest.mark.parametrize("resolver", RESOLVERS, ids=lambda r: type(r).__name__)
def test_singular_task_jacobian_gives_finite_bounded_velocities(crane, resolver):
    space = actuator_space(crane, random_configurations(crane, 5, seed=34, margin=0.1))
    J = space.J.copy()
    J[:, 1] = 2.0 * J[:, 0]  # both task rows parallel: rank 1
    space = dataclasses.replace(space, J=J)
    x_dot = resolver.resolve(space, np.tile([0.3, -0.2], (5, 1)))
    assert np.all(np.isfinite(x_dot))
    assert np.max(np.abs(x_dot)) < 1e3


def test_a_weight_near_singular_keeps_the_task_and_its_least_weighted_norm(tmp_path):
    """The crane with a telescope of 1e-12 kg and no payload: M_H is near singular (its ratio of
    eigenvalues about 1e-16), yet J_H W⁻¹ J_Hᵀ is not what loses rank. The min ẋᵀ M_H ẋ law
    still solves J_H ẋ = ẏ and is the KKT system's solution (well conditioned: M_H is positive
    definite on the null space of J_H, where the booms move), and its motion keeps the path as the
    unweighted law's does (it left it by 1.2 m when the law inverted W)."""
    shutil.copytree(bundled_root() / "hiab031", tmp_path / "crane")
    urdf = tmp_path / "crane" / "hiab031.urdf"
    light = '<mass value="1e-12"/>\n      <inertia ixx="0" ixy="0" ixz="0" iyy="1e-12"'
    text = urdf.read_text().replace(
        '<mass value="36"/>\n      <inertia ixx="0" ixy="0" ixz="0" iyy="6.4827"', light
    )
    urdf.write_text(text.replace('izz="6.4827"', 'izz="1e-12"'))
    toml = tmp_path / "crane" / "robot.toml"
    toml.write_text(toml.read_text().replace("payload = 100.0", "payload = 0.0"))
    crane = load_robot(toml)
    space = actuator_space(crane, random_configurations(crane, 30, seed=35, margin=0.02))
    eigenvalues = np.linalg.eigvalsh(space.M_H)
    assert (eigenvalues[:, 0] / eigenvalues[:, -1]).max() < 1e-12
    y_dot = np.random.default_rng(36).normal(scale=0.5, size=(30, crane.m))
    law = MinKineticEnergy()
    for x_dot in both_ways(law, crane, space, y_dot):
        np.testing.assert_allclose(
            np.einsum("kij,kj->ki", space.J_H, x_dot), y_dot, rtol=1e-9, atol=1e-10
        )
        expected = [
            constrained_least_squares(W, J_H, y, np.zeros(crane.n))
            for W, J_H, y in zip(space.M_H, space.J_H, y_dot)
        ]
        np.testing.assert_allclose(x_dot, expected, rtol=1e-7, atol=1e-9)
    cycle = WorkCycle.from_toml(crane.task_file, dimension=crane.m)
    _, start = default_start(crane, cycle["1-2"])
    errors = [
        simulate(crane, resolver, cycle["1-2"], start).max_tracking_error[0]
        for resolver in (law, MinVelocityNorm())
    ]
    assert errors[0] < 1e-4 and errors[1] < 1e-4, errors
