"""The compiled core (`redundancy._core`) against what it replaces: Pinocchio's own Python calls
for the pass, the closed forms of a cylinder's span and of the laws' kernel, to 1e-12
relative; and Python kinds and laws of a user's own, through every path."""

import gc
import pickle
import warnings
import weakref
from dataclasses import fields
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from sampling import random_configurations, random_velocities
from test_searches import GearedCylinder

from redundancy import (
    Controller,
    InvalidInputError,
    RedundancyError,
    _core,
    actuator_space,
    bundled_robots,
    global_optimum,
    load_robot,
)
from redundancy.model.actuators import ActuatorSet
from redundancy.planning.cycles import repeat
from redundancy.planning.integrate import MAX_SINGULAR, MAX_STEPS, TABLEAU
from redundancy.planning.starts import improved_start
from redundancy.planning.tasks import SAME_TIME
from redundancy.resolution import laws
from redundancy.resolution.laws import (
    SINGULAR_RATIO,
    GradientProjection,
    MinFlow,
    MinKineticEnergy,
    MinVelocityNorm,
    Resolver,
    State,
    Step,
    compiled_rates,
)
from redundancy.resolution.objectives import Objective
from redundancy.resolution.state import SINGULAR_TOLERANCE, _evaluated, evaluate

WORLD = pin.LOCAL_WORLD_ALIGNED
MIMIC = Path(__file__).parent / "fixtures" / "intake" / "mimic" / "robot.toml"
MIMIC_CHAIN = Path(__file__).parent / "fixtures" / "intake" / "mimic_chain" / "chain.urdf"
MASSLESS = Path(__file__).parent / "fixtures" / "intake" / "massless" / "robot.toml"
NONE = np.empty(0)  # no breaks in a segment: the loop may step anywhere in it


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
    and N, at states and velocities of every bundled robot (and one with a mimic joint). The
    point's rate is J̇_p = J̇_v − [p]× J̇_ω − [ṗ]× J_ω, of the spatial Jacobian's rate [J̇_v; J̇_ω]
    (`test_derivatives` checks it against finite differences)."""
    q = random_configurations(robot, 8, seed=50, margin=0.01)
    v = random_velocities(robot, 8, seed=51)
    moving = robot.kinematics(q, v)
    model, data = robot.model, robot.model.createData()
    for i in range(len(q)):
        pin.computeJointJacobiansTimeVariation(model, data, q[i], v[i])
        for frame, slot in moving.slots.items():
            position = pin.updateFramePlacement(model, data, frame).translation
            six = pin.getFrameJacobian(model, data, frame, WORLD)
            spatial = pin.getFrameJacobianTimeVariation(model, data, frame, pin.WORLD)
            velocity = six[:3] @ v[i]
            rate = (
                spatial[:3]
                - np.cross(position, spatial[3:], axis=0)
                - np.cross(velocity, six[3:], axis=0)
            )
            assert_equal_relative(moving.positions[i, slot], position)
            assert_equal_relative(moving.jacobians[i, slot], six[:3])
            assert_equal_relative(moving.angular[i, slot], six[3:])
            assert_equal_relative(moving.jacobian_rates[i, slot], rate)
            assert_equal_relative(moving.velocities[i, slot], velocity)
    if robot.kinematic_only:
        return
    M, N = robot.mass_matrices(q), robot.nonlinear(q, v)
    for i in range(len(q)):
        upper = pin.crba(model, data, q[i])
        assert_equal_relative(M[i], np.triu(upper) + np.triu(upper, 1).T)
        assert_equal_relative(N[i], pin.nonLinearEffects(model, data, q[i], v[i]))


def test_m_under_a_mimic_joint_solves_inverse_dynamics_at_every_call():
    """M(q) a = τ(q, 0, a) − τ(q, 0, 0) (Eq. 18, τ by RNEA) on an arm whose middle joint mimics
    the first, with moving joints below it, and M the same at every call, in a batch and one
    state at a time: Pinocchio 4.1's CRBA in its default convention adds the mimic joint's share
    again at each call there (M₀₁ 0.85, then 1.72, 2.60 kg m on this arm)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # joints driven directly (Identity)
        robot = load_robot(MIMIC_CHAIN)
    model, data, n = robot.model, robot.model.createData(), robot.n
    assert len(model.mimicking_joints) == 1
    q = random_configurations(robot, 6, seed=61, margin=0.05)
    first = robot.mass_matrices(q)
    for _ in range(3):
        np.testing.assert_array_equal(robot.mass_matrices(q), first)
    for i in range(len(q)):
        np.testing.assert_array_equal(robot.mass_matrices(q[i : i + 1])[0], first[i])
        rest = pin.rnea(model, data, q[i], np.zeros(n), np.zeros(n))
        columns = [pin.rnea(model, data, q[i], np.zeros(n), a) - rest for a in np.eye(n)]
        assert_equal_relative(first[i], np.transpose(columns))
        assert np.linalg.eigvalsh(first[i]).min() > 0


def test_the_compiled_evaluation_equals_python_s_and_the_closed_forms(robot):
    """One call of the core per batch (`Robot.evaluator`) gives what the pass, each group of
    kinds and the task point give through Python, and J_H = J A⁻¹, M_H = A⁻ᵀ M A⁻¹ and
    N_H = A⁻ᵀ N − M_H Ȧ q̇ as numpy's inverses give them, on every bundled robot."""
    q = random_configurations(robot, 6, seed=59, margin=0.05)
    v = random_velocities(robot, 6, seed=60)
    ours, theirs = evaluate(robot, q, v), _evaluated(robot, q, v)
    assert robot.evaluator() is not None and "J_H" in vars(ours) and "J_H" not in vars(theirs)
    for made in (ours, ours.kinematics):  # made past __init__: every field set all the same
        assert {f.name for f in fields(made)} <= vars(made).keys()
    for name in ("x", "A", "y", "J", "J_H", "x_dot", "A_dot"):
        assert_equal_relative(getattr(ours, name), getattr(theirs, name))
    for name in ("positions", "jacobians", "angular", "velocities", "jacobian_rates"):
        assert_equal_relative(getattr(ours.kinematics, name), getattr(theirs.kinematics, name))
    A_inv = np.linalg.inv(ours.A)
    assert_equal_relative(ours.J_H, ours.J @ A_inv)
    assert_equal_relative(ours.joint_velocities(ours.x_dot), v)
    if robot.kinematic_only:
        return
    M_H = A_inv.mT @ ours.M @ A_inv
    assert_equal_relative(ours.M_H, M_H)
    N = robot.nonlinear(q, v)
    expected = (A_inv.mT @ N[..., None] - M_H @ ours.A_dot @ v[..., None])[..., 0]
    assert_equal_relative(ours.N_H, expected)
    assert_equal_relative(theirs.N_H, expected)


def test_the_core_s_solve_refuses_a_singular_matrix_as_numpy_does():
    with pytest.raises(np.linalg.LinAlgError, match="Singular matrix"):
        _core.solve(np.zeros((1, 3, 3)), np.ones((1, 3)))


@pytest.mark.parametrize("n", range(1, 9))
def test_the_core_s_derivations_equal_numpy_s_at_every_size(n):
    """J_H = J A⁻¹, M_H = A⁻ᵀ M A⁻¹ and N_H = A⁻ᵀ N − M_H Ȧ q̇ by the core's factors of Aᵀ
    (fixed-size kernels up to n = 6, dynamic beyond) against numpy's solves, on matrices that
    need row pivoting (small leading entries), with the singular ones flagged."""
    rng = np.random.default_rng(n)
    k, m = 50, max(1, n - 1)
    A = rng.normal(size=(k, n, n)) + 3 * np.eye(n)[::-1]  # the large entries off the diagonal
    A[:, 0, 0] *= 1e-3
    A[-1] = np.outer(np.arange(1, n + 1), np.ones(n)) if n > 1 else 0.0  # singular
    J = rng.normal(size=(k, m, n))
    root = rng.normal(size=(k, n, n))
    M = root @ root.mT + n * np.eye(n)
    N, v, A_dot = rng.normal(size=(k, n)), rng.normal(size=(k, n)), rng.normal(size=(k, n, n))
    J_H, bad = _core.derive(A, J, SINGULAR_TOLERANCE)
    assert bad.tolist() == [False] * (k - 1) + [True]
    good = slice(0, k - 1)
    A_T = A[good].mT
    assert_equal_relative(J_H[good], np.linalg.solve(A_T, J[good].mT).mT)
    A_inv = np.linalg.inv(A[good])
    M_H = _core.inertias(A[good], M[good])
    assert_equal_relative(M_H, A_inv.mT @ M[good] @ A_inv)
    N_H = _core.biases(A[good], N[good], M_H, A_dot[good], v[good])
    expected = np.linalg.solve(A_T, N[good][..., None])[..., 0]
    assert_equal_relative(N_H, expected - (M_H @ A_dot[good] @ v[good][..., None])[..., 0])


def test_the_cylinder_kind_equals_its_closed_form():
    """x = |d|, A rows uᵀ ∂d/∂q and Ȧ rows u̇ᵀ ∂d/∂q + uᵀ d(∂d/∂q)/dt, u̇ = (I − u uᵀ) ḋ / x, of
    cylinders between random tracked points (d the rod's point less the base's)."""
    rng = np.random.default_rng(52)
    positions, velocities = rng.normal(size=(2, 7, 6, 3))
    jacobians, rates = rng.normal(size=(2, 7, 6, 3, 4))
    q, v = rng.normal(size=(2, 7, 4))
    kinds, slots = np.ones(3, np.intc), np.array([[0, 1, 0, 0], [2, 3, 0, 0], [5, 4, 0, 0]])
    numbers = np.zeros((3, 3))
    length, rows, rate_rows, ends, status = _core.actuate(
        kinds, slots, numbers, q, positions, jacobians, v, velocities, rates
    )

    def relative(points):
        return points[:, slots[:, 1]] - points[:, slots[:, 0]]

    d, d_dot, jacobian, rate = map(relative, (positions, velocities, jacobians, rates))
    x = np.sqrt((d * d).sum(2))
    u = d / x[..., None]
    u_dot = (d_dot - u * (u * d_dot).sum(2)[..., None]) / x[..., None]
    assert_equal_relative(length, x)
    assert_equal_relative(rows, np.einsum("kci,kcij->kcj", u, jacobian))
    expected = np.einsum("kci,kcij->kcj", u_dot, jacobian) + np.einsum("kci,kcij->kcj", u, rate)
    assert_equal_relative(rate_rows, expected)
    assert_equal_relative(ends, positions[:, slots[:, 1]])
    assert not status.any()
    assert _core.actuate(kinds, slots, numbers, q, positions, jacobians)[2] is None


def test_a_joint_driven_directly_is_its_coordinate_plus_its_offset():
    """x = q_j + offset, A row e_j, Ȧ row 0, whatever the tracked frames."""
    rng = np.random.default_rng(56)
    q, v = rng.normal(size=(2, 5, 3))
    positions, jacobians = rng.normal(size=(5, 1, 3)), rng.normal(size=(5, 1, 3, 3))
    velocities, rates = rng.normal(size=(5, 1, 3)), rng.normal(size=(5, 1, 3, 3))
    numbers = np.array([[2, 0.25, 0], [0, -1.5, 0]])
    x, rows, rate_rows, _, status = _core.actuate(
        np.zeros(2, np.intc),
        np.zeros((2, 4), np.intp),
        numbers,
        q,
        positions,
        jacobians,
        v,
        velocities,
        rates,
    )
    assert_equal_relative(x, q[:, [2, 0]] + [0.25, -1.5])
    assert_equal_relative(rows, np.broadcast_to(np.eye(3)[[2, 0]], rows.shape))
    assert_equal_relative(rate_rows, np.zeros_like(rows))
    assert not status.any()


def test_the_core_refuses_a_kind_it_does_not_know():
    with pytest.raises(ValueError, match="actuator 0 is not a kind the core knows"):
        _core.actuate(
            np.array([7], np.intc),
            np.zeros((1, 4), np.intp),
            np.zeros((1, 3)),
            np.zeros((1, 3)),
            np.zeros((1, 1, 3)),
            np.zeros((1, 1, 3, 3)),
        )


def gram_solution(J_H, W, z, y_dot, ratio):
    """The law's closed form: ẋ = J_W⁺ J_H d₀ + z, J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹, where d₀ =
    J_Hᵀ (G + λ² I)⁻¹ (ẏ − J_H z), G = J_H J_Hᵀ, λ² by `redundancy.resolution.laws`' rule from
    G's eigenvalues (undamped, J_H d₀ = ẏ − J_H z and ẋ = J_W⁺ (ẏ − J_H z) + z)."""
    G = J_H @ J_H.mT
    eigenvalues = np.linalg.eigvalsh(G)
    threshold = ratio * eigenvalues[:, -1]
    conditioned = np.linalg.det(G) >= ratio * np.trace(G, axis1=1, axis2=2) ** G.shape[-1]
    share = np.clip(eigenvalues[:, 0] / threshold, 0, 1)
    damping = np.where(conditioned, 0.0, threshold * (1 - share**2))
    target = y_dot - (J_H @ z[..., None])[..., 0]
    damped = G + damping[:, None, None] * np.eye(G.shape[-1])
    d_0 = J_H.mT @ np.linalg.solve(damped, target[..., None])
    W_inv_J_T = np.linalg.solve(W, J_H.mT)
    return (W_inv_J_T @ np.linalg.solve(J_H @ W_inv_J_T, J_H @ d_0))[..., 0] + z


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


def test_the_compiled_right_hand_side_refuses_times_that_are_not_one_per_state(crane):
    rates = compiled_rates(crane, MinVelocityNorm())
    q = np.tile((crane.lower + crane.upper) / 2, (3, 1))
    with pytest.raises(ValueError, match=r"t must have shape \(r,\), one time per state"):
        rates(np.zeros(2), q, np.array([0.5, 0.0]))


# The integration loop's last arguments where the strokes do not matter: no error allowance, no
# motion stopped past a stroke, no ends of steps kept, the documented caps on steps.
PLAIN = (0.0, False, False, MAX_STEPS, MAX_SINGULAR)


def test_the_integration_loop_refuses_states_it_cannot_read(crane):
    """The core's loop integrates only what it can read: states of another robot's n come back
    as None from the compiled right-hand side (Python then names what is wrong), and a Python
    right-hand side whose q̇, x or flags are not one row per state raise, never read past them."""
    q = np.tile((crane.lower + crane.upper) / 2, (3, 1))
    velocity = np.array([0.5, 0.0])

    def loop(rates, starts):
        zeros, n = np.zeros_like(starts), starts.shape[1]
        flags, bounds = np.zeros(len(starts), dtype=bool), (np.full(n, -np.inf), np.full(n, np.inf))
        return _core.dormand_prince(
            rates,
            velocity,
            starts,
            zeros,
            flags,
            1.0,
            NONE,
            SAME_TIME,
            1e-6,
            *TABLEAU,
            *bounds,
            *PLAIN,
        )

    assert loop(compiled_rates(crane, MinVelocityNorm()), np.zeros((3, 4))) is None
    short = (None, np.zeros((2, 3)), np.zeros(3, dtype=bool), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"gives q̇ and x \(r, n\), and bad \(r,\)"):
        loop(lambda t, states: short, q)


def test_a_step_to_the_end_lands_on_it():
    """A step that would stop an ulp short of the end goes to it: a step of an ulp followed,
    its sample an ulp after the last, and ẍ by differences of ẋ divided by that ulp (a study
    of a pump energy failed on a forestry crane's segment of √13 s so). At a constant q̇ the
    error is 0 and each step is ten times the last: 0.01, 0.1 and 1 s end at 1.11 s."""

    def steps(duration):
        def rates(t, states):
            return None, np.ones_like(states), np.zeros(len(t), dtype=bool), states

        ones, limits = np.ones((1, 1)), (np.full(1, -np.inf), np.full(1, np.inf))
        found = _core.dormand_prince(
            rates, None, ones, ones, np.zeros(1, dtype=bool), duration, NONE, SAME_TIME, 1e-6,
            *TABLEAU, *limits, *PLAIN,
        )  # fmt: skip
        return found[1] + found[2], found[3][:, 0]  # the steps' ends and starts' q

    ends, _ = steps(100.0)
    np.testing.assert_allclose(ends[:4], [0.01, 0.11, 1.11, 11.11], rtol=1e-15)
    duration = np.nextafter(ends[2], np.inf)  # an ulp past the third step's end
    ends, q = steps(duration)
    assert len(ends) == 3 and ends[-1] == duration and np.diff(ends).min() > 1e-3
    np.testing.assert_allclose(q, [1.0, 1.01, 1.11], rtol=1e-15)  # q = 1 + t


def test_the_loop_refuses_arrays_that_do_not_fit_and_freezes_a_start_it_cannot_step(crane):
    """The loop's own arrays are checked against q before it writes its copies of them, and a
    Python right-hand side's flags are read as their values, whatever their strides. A q̇ that
    is NaN but not flagged bad makes the step's error NaN: the start is frozen, not stepped
    forever."""
    q = np.tile((crane.lower + crane.upper) / 2, (4, 1))
    tableau, strokes = list(TABLEAU), (np.full(3, -np.inf), np.full(3, np.inf))

    def loop(rates, f=None, failed=None, duration=1.0, c=tableau[0], a=tableau[1], e=tableau[2]):
        f = np.zeros_like(q) if f is None else f
        failed = np.zeros(len(q), dtype=bool) if failed is None else failed
        return _core.dormand_prince(
            rates, None, q, f, failed, duration, NONE, SAME_TIME, 1e-6, c, a, e, *strokes, *PLAIN
        )

    def still(flags):  # a right-hand side at rest, its flags given as ``flags(r)``
        return lambda t, states: (None, np.zeros_like(states), flags(len(t)), states)

    for wrong in (
        {"f": np.zeros((1, 3))},
        {"failed": np.zeros(1, dtype=bool)},
        {"duration": np.nan},
        {"c": np.zeros(0), "a": np.zeros((0, 0)), "e": np.zeros(1)},
        {"e": tableau[2][:-1]},
    ):
        with pytest.raises(ValueError, match=r"must|tableau"):
            loop(still(lambda r: np.zeros(r, dtype=bool)), **wrong)
    # the last start flagged bad, by flags every other value of a longer array, or reversed
    q[:, 0] += [0.0, 0.01, 0.02, 0.03]
    last = lambda states: states[:, 0] > q[2, 0]  # noqa: E731
    for view in (lambda b: b.repeat(2)[::2], lambda b: b[::-1].copy()[::-1]):

        def flagged(t, states, view=view):  # at rest, the last start's flag True
            return None, np.zeros_like(states), view(last(states)), states

        found = loop(flagged)
        assert found[-3].tolist() == [False, False, False, True] and len(found[0])

    def nan(t, states):  # q̇ NaN, not flagged bad
        return None, np.full_like(states, np.nan), np.zeros(len(t), dtype=bool), states

    frozen = loop(nan)
    assert frozen[-3].all() and len(frozen[0]) == 0  # every start failed, no step accepted


def test_the_core_s_kernels_refuse_arrays_that_do_not_fit_and_ratios_outside_0_1():
    """Arrays of the right rank but a wrong last size are refused, not read past; a singular
    tolerance or a law's ratio of 0, NaN or above 1 is refused, not taken to pass a singular
    matrix; a law for no task coordinates (m = 0) gives its null-space term alone."""
    n, eye = 4, np.eye(4)[None]
    with pytest.raises(ValueError, match=r"M must have shape \(k, n, n\)"):
        _core.inertias(eye, np.ones((1, n, 1)))
    with pytest.raises(ValueError, match=r"M_H must have shape \(k, n, n\)"):
        _core.biases(eye, np.ones((1, n)), np.ones((1, n, 1)), eye, np.ones((1, n)))
    with pytest.raises(ValueError, match="n ≥ 1"):
        _core.derive(np.zeros((1, 0, 0)), np.zeros((1, 2, 0)), SINGULAR_TOLERANCE)
    for ratio in (0.0, -1.0, np.nan, 2.0):
        with pytest.raises(ValueError, match=r"must lie in \(0, 1\]"):
            _core.derive(eye, np.ones((1, 2, n)), ratio)
        with pytest.raises(ValueError, match=r"must lie in \(0, 1\]"):
            _core.resolve(np.ones((1, 2, n)), np.ones((1, 2)), None, None, ratio)
    z = np.arange(1.0, n + 1)[None]
    free = _core.resolve(np.zeros((1, 0, n)), np.zeros((1, 0)), None, z, SINGULAR_RATIO)
    assert np.array_equal(free, z)


def test_newton_refuses_shapes_that_do_not_fit_the_robot(crane):
    """The core's Newton loop takes the robot's q (k, n), one target per row of the m + r values
    its pass gives (the task's, and the held actuators': n of them, or fewer for the closest
    configuration to a point), and the joint limits (n,): anything else is refused before it
    is read."""
    held = crane.held_pass(crane.actuators.part([2]))
    q = np.tile((crane.lower + crane.upper) / 2, (3, 1))
    target = np.tile([3.5, -0.5, 0.8], (3, 1))
    limits = (crane.lower, crane.upper)
    tool_alone = crane.held_pass(crane.actuators.part([]))
    for passed, goal in ((held, target), (tool_alone, target[:, :2])):
        fine = _core.newton(passed, q, goal, None, 10, False, *limits, 1e-12, 1e-10, 1e-12)
        assert fine is not None and fine[0].shape == (3, 3)
    for start, goal, lower in (
        (q, target[:1], crane.lower),  # a target for one row of three
        (q[:, :2], target, crane.lower),  # another robot's n
        (q, target[:, :2], crane.lower),  # a target short of the held actuator's value
        (q, target, crane.lower[:2]),  # limits short of n
    ):
        with pytest.raises(ValueError, match="newton takes the robot's q"):
            _core.newton(held, start, goal, None, 10, True, lower, crane.upper, 1e-12, 1e-10, 1e-12)


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
    assert geared.evaluator() is None  # evaluated through Python, derived by the core
    space = actuator_space(geared, q)
    assert_equal_relative(space.x[:, 2], 2 * actuator_space(crane, q).x[:, 2])
    assert_equal_relative(space.J_H, space.J @ np.linalg.inv(space.A))
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


def built_in_laws(robot):
    """Every law of the toolkit the robot can run: the flow weights need its hydraulics, the
    kinetic energy its masses."""
    laws = [MinVelocityNorm(), GradientProjection(gain=2.0)]
    if not robot.kinematic_only:
        laws.append(MinKineticEnergy())
    if robot.hydraulics is not None:
        laws.append(MinFlow())
    return laws


def test_the_controller_steps_as_the_resolver_on_every_robot_and_law(robot):
    """One compiled call per step gives `Resolver.step`'s ẋ, q̇ and y to 1e-12 relative, for
    every built-in law, on every bundled robot (the excavator's linkage, the Panda's joints
    driven directly) and one with a mimic joint."""
    q = random_configurations(robot, 10, seed=57, margin=0.05)
    y_dot = np.random.default_rng(58).normal(scale=0.5, size=(10, robot.m))
    for law in built_in_laws(robot):
        controller = Controller(robot, law)
        assert controller.is_compiled
        for qi, yi in zip(q, y_dot):
            ours, theirs = controller.step(qi, yi), law.step(robot, qi, yi)
            assert isinstance(ours, Step)
            for mine, reference in zip(ours, theirs):
                assert_equal_relative(mine, reference)


def test_a_users_own_kind_or_law_steps_through_the_controller_in_python(crane, geared):
    """The geared telescope (a user's kind) or the slow-telescope law (a user's law): the
    controller runs `Resolver.step`, and says so."""
    q, y_dot = np.array([1.7, 1.0, 0.7]), np.array([0.3, -0.2])
    for robot, law in ((geared, MinVelocityNorm()), (crane, SlowTelescope())):
        controller = Controller(robot, law)
        assert not controller.is_compiled
        for mine, reference in zip(controller.step(q, y_dot), law.step(robot, q, y_dot)):
            assert_equal_relative(mine, reference)


STEP_ERRORS = [
    ([1.7, np.nan, 0.7], [0.3, -0.2], "q contains NaN or infinite values"),
    ([1.7, 1.0, 0.7], [np.inf, 0.0], "y_dot contains NaN or infinite values"),
    ([1.7, 1.0, 0.7], [0.0, 0.0, 0.0], "y_dot must have shape (2,)"),
    ([1.7, 1.0], [0.0, 0.0], "q must have shape (3,)"),
    ([[1.7, 1.0, 0.7]] * 2, [0.0, 0.0], "a step takes one q (3,) and one y_dot (2,)"),
    ([0.0, 0.0, 0.0], [1.0, 1.0], "actuator Jacobian A is singular at q = [0.0, 0.0, 0.0]"),
]


@pytest.mark.parametrize("q, y_dot, message", STEP_ERRORS)
def test_the_controller_refuses_what_the_resolver_refuses_in_the_same_words(
    crane, q, y_dot, message
):
    """A NaN, an infinity, a wrong shape or a singular A: the compiled step refuses it with
    `Resolver.step`'s one line."""
    law = MinKineticEnergy()
    with pytest.raises(RedundancyError) as theirs:
        law.step(crane, np.array(q), np.array(y_dot))
    with pytest.raises(RedundancyError) as ours:
        Controller(crane, law).step(np.array(q), np.array(y_dot))
    assert type(ours.value) is type(theirs.value)
    assert str(ours.value) == str(theirs.value)
    assert message in str(ours.value)


def fallbacks(monkeypatch) -> list:
    """The states a controller built from now on hands to its Python path (`python_state`)."""
    handed: list = []
    python = laws.python_state
    monkeypatch.setattr(laws, "python_state", lambda robot, q: handed.append(q) or python(robot, q))
    return handed


def test_the_controllers_state_is_the_actuator_space_on_every_robot(robot, monkeypatch):
    """One compiled call gives `actuator_space`'s x, A and J_H at a state, and M_H as its
    defining equation, A⁻ᵀ M A⁻¹ with M by Pinocchio's own CRBA, to 1e-12 relative, on every
    bundled robot and one with a mimic joint (M_H None on a robot without masses); none of
    them through the Python path."""
    handed = fallbacks(monkeypatch)
    controller = Controller(robot, MinVelocityNorm())
    assert controller.is_compiled
    model = robot.model
    data = model.createData()
    for q in random_configurations(robot, 6, seed=59, margin=0.05):
        state, space = controller.state(q), actuator_space(robot, q)
        assert isinstance(state, State)
        for mine, reference in zip(state[:3], (space.x[0], space.A[0], space.J_H[0])):
            assert_equal_relative(mine, reference)
        if robot.kinematic_only:
            assert state.M_H is None
            continue
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        inverse = np.linalg.inv(space.A[0])
        assert_equal_relative(state.M_H, inverse.T @ M @ inverse)
    assert not handed


def test_the_controllers_state_has_no_M_H_on_a_robot_without_masses(monkeypatch):
    """A kinematic-only robot: the compiled state's x, A and J_H are `actuator_space`'s, and
    M_H, undefined, is None."""
    with pytest.warns(UserWarning, match="the robot is kinematic only"):
        robot = load_robot(MASSLESS)
    assert robot.kinematic_only
    handed = fallbacks(monkeypatch)
    controller = Controller(robot, MinVelocityNorm())
    assert controller.is_compiled
    for q in random_configurations(robot, 4, seed=60, margin=0.05):
        state, space = controller.state(q), actuator_space(robot, q)
        assert state.M_H is None
        for mine, reference in zip(state[:3], (space.x[0], space.A[0], space.J_H[0])):
            assert_equal_relative(mine, reference)
    assert not handed


def test_a_users_own_kind_gives_its_state_through_the_controller_in_python(geared):
    """The geared telescope, a user's kind: the controller's state is `actuator_space`'s."""
    q = np.array([1.7, 1.0, 0.7])
    state, space = Controller(geared, MinVelocityNorm()).state(q), actuator_space(geared, q)
    for mine, reference in zip(state, (space.x[0], space.A[0], space.J_H[0], space.M_H[0])):
        assert_equal_relative(mine, reference)


def test_a_users_own_law_reads_its_states_compiled(crane, monkeypatch):
    """A state does not depend on the law: a controller of a user's own law steps in Python
    (`Resolver.step`, to the last bit) and reads its states by one compiled call, none handed
    to the Python path, equal to `actuator_space`'s."""
    handed = fallbacks(monkeypatch)
    law = SlowTelescope()
    controller = Controller(crane, law)
    assert not controller.is_compiled
    y_dot = np.array([0.2, -0.1])
    for q in random_configurations(crane, 4, seed=61, margin=0.05):
        state, space = controller.state(q), actuator_space(crane, q)
        for mine, reference in zip(state, (space.x[0], space.A[0], space.J_H[0], space.M_H[0])):
            assert_equal_relative(mine, reference)
        for mine, reference in zip(controller.step(q, y_dot), law.step(crane, q, y_dot)):
            np.testing.assert_array_equal(mine, reference)
    assert not handed


STATE_ERRORS = [
    ([1.7, np.nan, 0.7], "q contains NaN or infinite values"),
    ([1.7, 1.0], "q must have shape (3,)"),
    ([0.0, 0.0, 0.0], "actuator Jacobian A is singular at q = [0.0, 0.0, 0.0]"),
]


@pytest.mark.parametrize("q, message", STATE_ERRORS)
def test_the_controllers_state_refuses_what_actuator_space_refuses_in_the_same_words(
    crane, q, message, monkeypatch
):
    """A NaN, a wrong shape or a singular A: the compiled state hands it to the Python path,
    which refuses it with `actuator_space`'s one line; two states at once, with its own."""
    with pytest.raises(RedundancyError) as theirs:
        actuator_space(crane, np.array(q))
    handed = fallbacks(monkeypatch)
    with pytest.raises(RedundancyError) as ours:
        Controller(crane, MinVelocityNorm()).state(np.array(q))
    assert len(handed) == 1
    assert type(ours.value) is type(theirs.value)
    assert str(ours.value) == str(theirs.value)
    assert message in str(ours.value)
    with pytest.raises(InvalidInputError, match=r"a state takes one q \(3,\); got shape \(2, 3\)"):
        Controller(crane, MinVelocityNorm()).state(np.ones((2, 3)))


def test_a_controller_is_freed_once_dropped(crane):
    """Its compiled object keeps the Python fallbacks, which must not keep the controller: a
    cycle through the core's object is one the garbage collector cannot see."""
    controller = Controller(crane, MinVelocityNorm())
    assert controller.is_compiled
    dropped = weakref.ref(controller)
    del controller
    gc.collect()
    assert dropped() is None


def test_a_compiled_controller_is_pickled_as_its_robot_and_law(crane):
    """Sent to another process (pickled), it is built again there: compiled, and stepping the
    same to the last bit."""
    controller = Controller(crane, MinKineticEnergy())
    copy = pickle.loads(pickle.dumps(controller))
    assert copy.is_compiled and type(copy.law) is MinKineticEnergy
    q = random_configurations(crane, 5, seed=63, margin=0.05)
    for state in q:
        np.testing.assert_array_equal(
            copy.step(state, [0.3, -0.2]).x_dot, controller.step(state, [0.3, -0.2]).x_dot
        )


def test_a_robot_with_its_compiled_passes_pickles_with_every_protocol(crane):
    """A robot that has evaluated states holds compiled passes, which pickle protocols 0 and 1
    cannot rebuild: pickling it so aborted the interpreter. The passes are not sent; the copy
    builds its own and evaluates the same states to the last bit."""
    q = random_configurations(crane, 3, seed=64, margin=0.05)
    space = actuator_space(crane, q)
    for protocol in range(pickle.HIGHEST_PROTOCOL + 1):
        copy = actuator_space(pickle.loads(pickle.dumps(crane, protocol=protocol)), q)
        np.testing.assert_array_equal(copy.x, space.x)
        np.testing.assert_array_equal(copy.M_H, space.M_H)


def test_the_held_law_solves_its_defining_equations(crane):
    """`_core.held`: the task resolved, J_H ẋ = ẏ, and the held actuators at their rates,
    ẋ_h = E_h ẋ, to 1e-12 relative, on states of the crane with x3 or x1 held; numpy's
    LinAlgError where [J_H; E_h] is singular."""
    space = actuator_space(crane, random_configurations(crane, 8, seed=61, margin=0.05))
    rng = np.random.default_rng(62)
    y_dot, held = rng.normal(size=(8, 2)), rng.normal(size=(8, 1))
    for rows in ([2], [0]):
        x_dot = _core.held(space.J_H, y_dot, rows, held)
        assert_equal_relative((space.J_H @ x_dot[..., None])[..., 0], y_dot)
        assert_equal_relative(x_dot[:, rows], held)
    J_H = space.J_H.copy()
    J_H[0, :, :2] = [[1.0, 2.0], [2.0, 4.0]]  # x1 and x2 alone cannot resolve the task
    with pytest.raises(np.linalg.LinAlgError, match="Singular matrix"):
        _core.held(J_H, y_dot, [2], held)


def test_the_controller_takes_a_robot_and_a_law(crane):
    with pytest.raises(InvalidInputError, match="a controller takes a law, a Resolver"):
        Controller(crane, "velocity")
    with pytest.raises(InvalidInputError, match="robot must be a Robot"):
        Controller("hiab031", MinVelocityNorm())
