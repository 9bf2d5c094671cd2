"""Resolvers against their defining equations: J_H ẋ = ẏ, and weighted minimality."""

import dataclasses

import numpy as np
import pytest
from sampling import random_configurations

from redundancy import actuator_space
from redundancy.resolvers import GradientProjection, MinKineticEnergy, MinVelocityNorm

RESOLVERS = [MinVelocityNorm(), MinKineticEnergy(), GradientProjection(gain=2.0)]


@pytest.fixture(scope="module")
def states(crane):
    q = random_configurations(crane, 40, seed=30, margin=0.02)
    y_dot = np.random.default_rng(31).normal(scale=0.5, size=(40, crane.m))
    return actuator_space(crane, q), y_dot


def null_space_directions(J_H, count, seed):
    """``count`` random directions in the null space of each J_H (k, m, n): (k, count, n)."""
    _, _, vt = np.linalg.svd(J_H)
    basis = vt[:, J_H.shape[1] :]  # (k, n − m, n)
    weights = np.random.default_rng(seed).normal(size=(len(J_H), count, basis.shape[1]))
    return weights @ basis


@pytest.mark.parametrize("resolver", RESOLVERS, ids=lambda r: type(r).__name__)
def test_every_resolver_tracks_the_task_velocity(states, resolver):
    space, y_dot = states
    x_dot = resolver.resolve(space, y_dot)
    np.testing.assert_allclose(
        np.einsum("kij,kj->ki", space.J_H, x_dot), y_dot, rtol=1e-10, atol=1e-12
    )


def test_min_velocity_solution_minimises_the_velocity_norm(states):
    space, y_dot = states
    x_dot = MinVelocityNorm().resolve(space, y_dot)
    others = x_dot[:, None] + 0.05 * null_space_directions(space.J_H, 20, seed=32)
    assert np.all(np.sum(others**2, axis=2) > np.sum(x_dot**2, axis=1)[:, None])


def test_min_energy_solution_minimises_the_kinetic_energy(states):
    space, y_dot = states
    x_dot = MinKineticEnergy().resolve(space, y_dot)
    others = x_dot[:, None] + 0.05 * null_space_directions(space.J_H, 20, seed=33)
    energy = np.einsum("ki,kij,kj->k", x_dot, space.M_H, x_dot)
    other_energy = np.einsum("kci,kij,kcj->kc", others, space.M_H, others)
    assert np.all(other_energy > energy[:, None])
    # ... and it is not the unweighted solution: the weighting matters on the crane.
    assert np.max(np.abs(x_dot - MinVelocityNorm().resolve(space, y_dot))) > 1e-3


def test_gradient_projection_adds_only_null_space_motion(states):
    space, y_dot = states
    resolver = GradientProjection(gain=2.0)
    extra = resolver.resolve(space, y_dot) - MinVelocityNorm().resolve(space, y_dot)
    assert np.max(np.abs(extra)) > 1e-3  # it does move the redundant coordinate
    np.testing.assert_allclose(np.einsum("kij,kj->ki", space.J_H, extra), 0, atol=1e-12)


def test_gradient_projection_pushes_actuators_towards_mid_stroke(crane, states):
    space, _ = states
    x_dot = GradientProjection(gain=2.0).resolve(space, np.zeros((len(space.x), crane.m)))
    middle = (crane.actuators.lower + crane.actuators.upper) / 2
    span = crane.actuators.upper - crane.actuators.lower
    # Φ grows along the motion: ∇Φ · ẋ ≥ 0 with ∇Φ = −(x − x̄)/Δx².
    growth = np.sum(-(space.x - middle) / span**2 * x_dot, axis=1)
    assert np.all(growth >= -1e-15)


@pytest.mark.parametrize("resolver", RESOLVERS, ids=lambda r: type(r).__name__)
def test_singular_task_jacobian_gives_finite_bounded_velocities(crane, resolver):
    space = actuator_space(crane, random_configurations(crane, 5, seed=34, margin=0.1))
    singular = space.J_H.copy()
    singular[:, 1] = 2.0 * singular[:, 0]  # both task rows parallel: rank 1
    space = dataclasses.replace(space, J_H=singular)
    x_dot = resolver.resolve(space, np.tile([0.3, -0.2], (5, 1)))
    assert np.all(np.isfinite(x_dot))
    assert np.max(np.abs(x_dot)) < 1e3
