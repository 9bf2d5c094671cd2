"""The compiled core (`redundancy._core`) against what it replaces: Pinocchio's own Python calls
for the pass, the closed forms of a cylinder's span and of the laws' kernel, to 1e-12
relative; and Python kinds and laws of a user's own, through every path."""

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from sampling import random_configurations, random_velocities
from test_searches import GearedCylinder

from redundancy import _core, actuator_space, bundled_robots, global_optimum, load_robot
from redundancy.model.actuators import ActuatorSet
from redundancy.planning.cycles import repeat
from redundancy.planning.starts import improved_start
from redundancy.resolution.laws import SINGULAR_RATIO, Resolver
from redundancy.resolution.objectives import Objective

WORLD = pin.LOCAL_WORLD_ALIGNED
MIMIC = Path(__file__).parent / "fixtures" / "intake" / "mimic" / "robot.toml"


def assert_equal_relative(ours, theirs):
    """Equal to 1e-12 of the largest magnitude."""
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12 * max(np.abs(theirs).max(), 1))


@pytest.fixture(scope="module", params=[*bundled_robots(), str(MIMIC)])
def robot(request):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # joints driven directly (Identity)
        return load_robot(request.param)


def test_the_compiled_pass_equals_pinocchios_python_calls(robot):
    """Every tracked frame's position, Jacobians, velocity and Jacobian rate, M (both triangles)
    and N, at states and velocities of every bundled robot (and one with a mimic joint)."""
    q = random_configurations(robot, 8, seed=50, margin=0.01)
    v = random_velocities(robot, 8, seed=51)
    moving = robot.kinematics(q, v)
    model, data = robot.model, robot.model.createData()
    for i in range(len(q)):
        pin.computeJointJacobiansTimeVariation(model, data, q[i], v[i])
        for frame, slot in moving.slots.items():
            position = pin.updateFramePlacement(model, data, frame).translation
            six = pin.getFrameJacobian(model, data, frame, WORLD)
            rate = pin.getFrameJacobianTimeVariation(model, data, frame, WORLD)
            assert_equal_relative(moving.positions[i, slot], position)
            assert_equal_relative(moving.jacobians[i, slot], six[:3])
            assert_equal_relative(moving.angular[i, slot], six[3:])
            assert_equal_relative(moving.jacobian_rates[i, slot], rate[:3])
            assert_equal_relative(moving.velocities[i, slot], six[:3] @ v[i])
    if robot.kinematic_only:
        return
    M, N = robot.mass_matrices(q), robot.nonlinear(q, v)
    for i in range(len(q)):
        upper = pin.crba(model, data, q[i])
        assert_equal_relative(M[i], np.triu(upper) + np.triu(upper, 1).T)
        assert_equal_relative(N[i], pin.nonLinearEffects(model, data, q[i], v[i]))


def test_the_span_kernel_equals_its_closed_form():
    """x = |d|, A rows uᵀ ∂d/∂q and Ȧ rows u̇ᵀ ∂d/∂q + uᵀ d(∂d/∂q)/dt, u̇ = (I − u uᵀ) ḋ / x."""
    rng = np.random.default_rng(52)
    d, d_dot = rng.normal(size=(2, 7, 3, 3))
    jacobian, rate = rng.normal(size=(2, 7, 3, 3, 4))
    length, rows, rate_rows = _core.span(d, jacobian, d_dot, rate)
    x = np.sqrt((d * d).sum(2))
    u = d / x[..., None]
    u_dot = (d_dot - u * (u * d_dot).sum(2)[..., None]) / x[..., None]
    assert_equal_relative(length, x)
    assert_equal_relative(rows, np.einsum("kci,kcij->kcj", u, jacobian))
    expected = np.einsum("kci,kcij->kcj", u_dot, jacobian) + np.einsum("kci,kcij->kcj", u, rate)
    assert_equal_relative(rate_rows, expected)
    assert _core.span(d, jacobian)[2] is None


def gram_solution(J_H, W, z, y_dot, ratio):
    """The law's closed form: ẋ = W⁻¹ J_Hᵀ (G + λ² I)⁻¹ (ẏ − J_H z) + z, G = J_H W⁻¹ J_Hᵀ, λ² by
    `redundancy.resolution.laws`' rule from G's eigenvalues."""
    W_inv_J_T = np.linalg.solve(W, J_H.mT)
    G = J_H @ W_inv_J_T
    eigenvalues = np.linalg.eigvalsh(G)
    threshold = ratio * eigenvalues[:, -1]
    conditioned = np.linalg.det(G) >= ratio * np.trace(G, axis1=1, axis2=2) ** G.shape[-1]
    share = np.clip(eigenvalues[:, 0] / threshold, 0, 1)
    damping = np.where(conditioned, 0.0, threshold * (1 - share**2))
    target = y_dot - (J_H @ z[..., None])[..., 0]
    damped = G + damping[:, None, None] * np.eye(G.shape[-1])
    return (W_inv_J_T @ np.linalg.solve(damped, target[..., None]))[..., 0] + z


@pytest.mark.parametrize("ratio", [SINGULAR_RATIO, 1.0], ids=["exact", "damped"])
def test_the_law_kernel_equals_its_closed_form(ratio):
    """Weighted, with a null-space term, at well-conditioned task Jacobians; with the threshold
    raised to 1 every state takes the damped branch."""
    rng = np.random.default_rng(53)
    J_H = rng.normal(size=(9, 2, 3))
    root = rng.normal(size=(9, 3, 3))
    W = root @ root.mT + 3 * np.eye(3)
    z, y_dot = rng.normal(size=(9, 3)), rng.normal(size=(9, 2))
    weighted = gram_solution(J_H, W, z, y_dot, ratio)
    assert_equal_relative(_core.resolve(J_H, y_dot, W, z, ratio), weighted)
    unweighted = gram_solution(J_H, np.broadcast_to(np.eye(3), W.shape), 0 * z, y_dot, ratio)
    assert_equal_relative(_core.resolve(J_H, y_dot, None, None, ratio), unweighted)


def test_the_law_kernel_refuses_mismatched_shapes():
    with pytest.raises(ValueError, match=r"W must have shape \(k, n, n\)"):
        _core.resolve(np.zeros((1, 2, 3)), np.zeros((1, 2)), np.eye(3), None, SINGULAR_RATIO)


class SlowTelescope(Resolver):
    """A user's own law: the telescope's speed weighs 4 times the cylinders', and a small
    null-space pull towards the fold cylinder's mid-stroke."""

    def weight(self, space):
        return np.broadcast_to(np.diag([1.0, 1.0, 4.0]), space.A.shape)

    def null_space(self, space):
        z = np.zeros_like(space.x)
        actuators = space.robot.actuators
        z[:, 1] = -0.01 * (space.x[:, 1] - (actuators.lower[1] + actuators.upper[1]) / 2)
        return z


@pytest.fixture(scope="module")
def geared(crane):
    """The crane with its telescope geared (`GearedCylinder`, a user's kind written in the
    search tests), its other actuators as built."""
    telescope = crane.actuators["x3"]
    maps = [a for a in crane.actuators if a.name != "x3"]
    maps.append(GearedCylinder("x3", telescope.joint, 0.0, 2 * 1.09, telescope.offset))
    robot = load_robot("hiab031")
    robot.actuators = ActuatorSet.bind(maps, robot.model)
    return robot


def test_a_users_own_kind_and_law_run_through_every_path(crane, geared, paper_cycle):
    """The geared telescope under the user's law: actuator space (the law solves J_H ẋ = ẏ
    with the least ẋᵀ W ẋ about z), the fast search, the bound and a cycle."""
    law = SlowTelescope()
    q = random_configurations(geared, 6, seed=54, margin=0.05)
    space = actuator_space(geared, q)
    assert_equal_relative(space.x[:, 2], 2 * actuator_space(crane, q).x[:, 2])
    y_dot = np.random.default_rng(55).normal(size=(6, 2))
    x_dot = law.resolve(space, y_dot)
    assert_equal_relative((space.J_H @ x_dot[..., None])[..., 0], y_dot)
    W, z = law.weight(space), law.null_space(space)
    assert_equal_relative(x_dot, gram_solution(space.J_H, W, z, y_dot, SINGULAR_RATIO))
    own = Objective("slow telescope", law, lambda s, v: (v * v).sum(1), "ẋᵀẋ", "m²/s²")
    segment = paper_cycle["1-2"]
    search = improved_start(geared, segment, own)
    assert search.best is not None and search.motion().within_limits[0]
    optimum = global_optimum(geared, segment, own, grids=(12, 24), search=search)
    assert optimum.bound <= search.best.peak * (1 + 1e-6)
    cycle = repeat(geared, paper_cycle, law, search.motion().q[0, 0], cycles=1)
    assert np.isfinite(cycle.drift).all()
