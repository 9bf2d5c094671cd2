"""The fixed-step method (the paper's simulation) along the paper's segments: tracking accuracy,
limits, failures. The adaptive method is checked against it in test_searches.py."""

import pickle
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from joint_space import fk, inverse_dynamics
from slewing3r_closed_form import slew_held_configuration

from redundancy import InvalidInputError, actuator_space, default_start, improved_start, load_robot
from redundancy.planning import integrate
from redundancy.planning.cycles import HeldReference
from redundancy.planning.ik import inverse_kinematics
from redundancy.planning.integrate import REPORT_TOLERANCE, simulate
from redundancy.planning.motions import simulate_path
from redundancy.planning.tasks import SAME_TIME, Chain, Polyline, Segment, WorkCycle, corners, jumps
from redundancy.resolution.laws import (
    SINGULAR_RATIO,
    GradientProjection,
    MinFlow,
    MinVelocityNorm,
    Resolver,
)
from redundancy.resolution.objectives import (
    ENERGY,
    LS_ENERGY,
    VELOCITY,
    Objective,
    integral,
    velocity_norm,
)

PLANAR = Path(__file__).parent / "data" / "planar4r"
SQUARED = Objective("joint_speeds", MinVelocityNorm(), velocity_norm, "q̇ᵀq̇", "rad²/s²", "integral")


@pytest.fixture(scope="module")
def cycle(crane):
    return WorkCycle.from_toml(crane.task_file, dimension=crane.m)


def reachable_starts(robot, segment, values):
    ik = inverse_kinematics(robot, segment.start, ["x3"], np.asarray(values)[:, None])
    return ik.q[ik.reached]


@pytest.mark.parametrize("segment_name", ["1-2", "2-3", "3-1"])
@pytest.mark.parametrize("resolver", [VELOCITY.resolver, ENERGY.resolver, GradientProjection()])
def test_tracking_error_stays_below_a_micrometre_on_every_paper_segment(
    crane, cycle, segment_name, resolver
):
    segment = cycle[segment_name]
    starts = reachable_starts(crane, segment, np.linspace(0.0, 1.09, 6))
    trajectory = simulate(crane, resolver, segment, starts, method="rk4")
    assert len(trajectory) >= 2
    assert trajectory.max_tracking_error.max() <= 1e-6
    np.testing.assert_allclose(
        trajectory.y[:, -1], np.tile(segment.end, (len(starts), 1)), atol=1e-6
    )


def test_the_recorded_velocities_are_those_of_the_motion(crane, cycle):
    """ẋ sampled from the resolver equals the time derivative of the integrated strokes x."""
    segment = cycle["2-3"]
    trajectory = simulate(
        crane, VELOCITY.resolver, segment, reachable_starts(crane, segment, [0.4]), method="rk4"
    )
    derivative = np.gradient(trajectory.x[0], trajectory.t[0], axis=0, edge_order=2)
    np.testing.assert_allclose(trajectory.x_dot[0, 1:-1], derivative[1:-1], atol=1e-5)


def test_actuator_forces_along_a_motion_match_inverse_dynamics(crane, cycle):
    segment = cycle["1-2"]
    trajectory = simulate(
        crane, VELOCITY.resolver, segment, reachable_starts(crane, segment, [1.0]), method="rk4"
    )
    q, t = trajectory.q[0], trajectory.t[0]
    v = np.gradient(q, t, axis=0, edge_order=2)
    a = np.gradient(v, t, axis=0, edge_order=2)
    inner = slice(5, -5)  # away from the one-sided differences at the ends
    tau = inverse_dynamics(crane, q[inner], v[inner], a[inner])
    states = trajectory.states
    A = states.A.reshape(len(t), crane.n, crane.n)[inner]
    expected = np.linalg.solve(np.swapaxes(A, 1, 2), tau[..., None])[..., 0]
    np.testing.assert_allclose(trajectory.forces[0, inner], expected, rtol=1e-3)


def test_accelerations_of_a_lone_motion_sampled_at_its_steps_are_taken_at_its_own_times(
    crane, cycle
):
    """ẍ of motions sampled at their adaptive steps is differenced at each motion's own times.
    A batch of one motion has one row of times, which used to pass for a uniform grid: its ẍ
    by fourth-order differences with the first interval as h was off by up to 1.3 m/s² (the
    motion's largest is 0.07), and its LS energy 8.5 % low, where the searches and the design
    maps integrate a probe alone. Alone or beside another start, the motion's ẍ is the same,
    and its LS energy within 0.2 % of the motion's on a 10 ms grid."""
    segment = cycle["1-2"]
    (a, b) = reachable_starts(crane, segment, [1.085, 1.0])
    resolver = LS_ENERGY.resolver
    alone = simulate(crane, resolver, segment, a[None], sparse=True)
    pair = simulate(crane, resolver, segment, np.stack([a, b]), sparse=True)
    count = alone.counts[0]
    np.testing.assert_allclose(alone.x_ddot[0, :count], pair.x_ddot[0, :count], atol=1e-12)
    grid = simulate(crane, resolver, segment, a[None], tolerance=1e-10)
    assert alone.score(LS_ENERGY)[0] == pytest.approx(grid.score(LS_ENERGY)[0], rel=2e-3)


def test_limits_are_flagged_with_actuator_time_and_excess(crane, cycle):
    segment = cycle["3-1"]
    values = np.linspace(0.0, 0.9, 10)
    trajectory = simulate(
        crane, VELOCITY.resolver, segment, reachable_starts(crane, segment, values), method="rk4"
    )
    lower, upper = crane.actuators.lower, crane.actuators.upper
    assert not trajectory.within_limits.all() and trajectory.within_limits.any()
    for i in range(len(trajectory)):
        inside = np.all((trajectory.x[i] >= lower - 1e-9) & (trajectory.x[i] <= upper + 1e-9))
        assert trajectory.within_limits[i] == inside
        violations = trajectory.violations(i)
        assert bool(violations) != inside
        for violation in violations:
            row = crane.actuators.names.index(violation.actuator)
            t = trajectory.t[i]
            span = (t >= violation.start) & (t <= violation.end)
            x = trajectory.x[i, span, row]
            past = lower[row] - x if violation.bound == "lower" else x - upper[row]
            assert past.max() == pytest.approx(violation.excess)
            assert np.all(past > 0)
        t = trajectory.t[i]
        for row, name in enumerate(crane.actuators.names):  # every sample past is in one
            x = trajectory.x[i, :, row]
            past = (x < lower[row] - 1e-9) | (x > upper[row] + 1e-9)
            spans = [(t >= v.start) & (t <= v.end) for v in violations if v.actuator == name]
            np.testing.assert_array_equal(np.any([past & False, *spans], axis=0), past)


def test_checking_named_actuators_only(crane, cycle):
    segment = cycle["3-1"]
    starts = reachable_starts(crane, segment, np.linspace(0.0, 0.9, 10))
    every = simulate(crane, ENERGY.resolver, segment, starts, method="rk4")
    paper = simulate(crane, ENERGY.resolver, segment, starts, checked=("x1", "x2"), method="rk4")
    assert not every.within_limits.any()  # the telescope leaves its stroke
    assert paper.within_limits.any()
    assert all(v.actuator in ("x1", "x2") for i in range(len(paper)) for v in paper.violations(i))


def test_a_start_at_a_singular_actuator_jacobian_is_frozen_and_flagged(crane):
    """At q1 = 0 the lift cylinder's line passes through joint 1: its torque arm a1 vanishes."""
    q = np.array([[0.0, 1.0, 0.5], [1.5, 1.0, 0.5]])
    y0 = fk(crane, q[1])
    segment = Segment("short", y0, y0 + np.array([-0.2, 0.0]), 0.5)
    trajectory = simulate(crane, VELOCITY.resolver, segment, q, method="rk4")
    assert trajectory.failed.tolist() == [True, False]
    assert trajectory.within_limits[0] == np.False_
    np.testing.assert_array_equal(trajectory.q[0], np.tile(q[0], (trajectory.t.shape[1], 1)))
    assert trajectory.max_tracking_error[1] <= 1e-6
    # sampled at the steps, a motion frozen at its start has that sample alone: no margin, at
    # rest; a dynamic objective (which reads ẍ) measures it, alone or beside a motion that runs
    for starts in (q[:1], q):
        frozen = simulate(crane, LS_ENERGY.resolver, segment, starts, sparse=True)
        assert frozen.failed[0] and frozen.counts[0] == 1
        assert frozen.margins[0] == -np.inf and not frozen.within_limits[0]
        assert np.all(frozen.x_ddot[0] == 0) and frozen.score(LS_ENERGY)[0] == 0
    assert frozen.score(LS_ENERGY)[1] > 0


def test_a_segment_of_the_wrong_dimension_is_refused(crane):
    segment = Segment("3d", np.zeros(3), np.ones(3), 0.5)
    with pytest.raises(InvalidInputError, match=r"3 coordinates.*task has 2"):
        simulate(crane, VELOCITY.resolver, segment, np.array([[1.5, 1.0, 0.5]]))


def test_the_closed_loop_converges_within_rk4s_stability_and_is_refused_beyond_it(crane, cycle):
    """The tracking error e obeys ė = −K e; one RK4 step multiplies it by R(−K h), R(z) = 1 + z
    + z²/2 + z³/6 + z⁴/24, below 1 in size only for K h < 2.785. At K h = 2.7 a tool started
    centimetres off the path returns to it (to within the lag so stiff a loop leaves the fixed
    step, 2e-5 m); at K h = 2.8 the method is refused."""
    segment = cycle["1-2"]
    start = reachable_starts(crane, segment, [1.0]) + np.array([0.0, 0.01, 0.0])
    motion = simulate(crane, VELOCITY.resolver, segment, start, method="rk4", gain=270.0)
    error = np.linalg.norm(motion.y[0] - segment.position(motion.t[0]), axis=1)
    assert error[0] > 0.02
    assert error[-1] < 1e-4
    with pytest.raises(InvalidInputError, match=r"gain = 280 1/s at time_step = 0.01 s makes"):
        simulate(crane, VELOCITY.resolver, segment, start, method="rk4", gain=280.0)


def test_a_motion_as_a_table_round_trips_its_arrays(crane, cycle):
    """`Trajectory.to_frame`: one row per sample, each column named with its unit, holding
    exactly the motion's t, q, x, ẋ, ẍ and F_H."""
    segment = cycle["2-3"]
    motion = simulate(crane, VELOCITY.resolver, segment, reachable_starts(crane, segment, [0.4]))
    frame = motion.to_frame()
    assert list(frame.columns[:4]) == [
        "t (s)",
        "q_boom1_joint (rad)",
        "q_boom2_joint (rad)",
        "q_telescope_joint (m)",
    ]
    forces = ["F_x1 (N)", "F_x2 (N)", "F_x3 (N)"]
    assert list(frame.columns[13:16]) == forces  # after t, q and x, ẋ, ẍ of each actuator
    # then the crane's circuit: each cylinder's load pressure and flow, the pump's flow and power
    assert list(frame.columns[16:]) == [
        "p_L_x1 (bar)",
        "Q_x1 (L/min)",
        "p_L_x2 (bar)",
        "Q_x2 (L/min)",
        "p_L_x3 (bar)",
        "Q_x3 (L/min)",
        "Q_pump (L/min)",
        "pump_power_LS (kW)",  # p_P Q_P under the crane's own supply
    ]
    np.testing.assert_array_equal(frame["t (s)"], motion.t[0])
    np.testing.assert_array_equal(frame.filter(like="q_").to_numpy(), motion.q[0])
    for part, values in (
        ("x_", motion.x),
        ("x_dot_", motion.x_dot),
        ("x_ddot_", motion.x_ddot),
        ("F_", motion.forces),
    ):
        columns = [f"{part}{name} " for name in crane.actuators.names]
        picked = frame[[c for c in frame.columns if any(c.startswith(p) for p in columns)]]
        np.testing.assert_array_equal(picked.to_numpy(), values[0])


def test_a_motion_as_a_table_names_the_supply_its_pump_power_is_under(crane, cycle, tmp_path):
    """The pump's power was "P_pump (kW)", which said neither that it is a power (p_P is the
    pump's pressure) nor under which supply: it is p_P Q_P under the machine's own."""
    text = (crane.task_file.parent / "robot.toml").read_text()
    table = text[text.index("[hydraulics]") :].replace('supply = "LS"', 'supply = "CP"')
    (tmp_path / "cp.toml").write_text(table)
    robot = load_robot("hiab031", hydraulics=tmp_path / "cp.toml")
    segment = cycle["2-3"]
    motion = simulate(robot, VELOCITY.resolver, segment, reachable_starts(robot, segment, [0.4]))
    power = motion.flows.power(robot.circuit().constant_pressure)[0]
    frame = motion.to_frame()
    np.testing.assert_allclose(frame["pump_power_CP (kW)"] * 1e3, power, rtol=1e-12)
    assert not [c for c in frame.columns if "LS" in c]


def test_a_motion_sent_to_another_process_is_sampled_there_as_here(crane, cycle):
    """A search's motions travel between processes (the study's cycle section, design maps):
    pickled with their steps and law, they are put on the grid alike on the other side, where
    the law's compiled right-hand side is built again."""
    segment = cycle["2-3"]
    starts = reachable_starts(crane, segment, [0.3, 0.7])
    motion = simulate(crane, VELOCITY.resolver, segment, starts, sparse=True)
    here = motion.on_grid()
    there = pickle.loads(pickle.dumps(motion)).on_grid()
    for name in ("t", "q", "x", "x_dot"):
        np.testing.assert_array_equal(getattr(there, name), getattr(here, name))


@pytest.mark.parametrize(
    "resolver", [VELOCITY.resolver, ENERGY.resolver, MinFlow(), GradientProjection()]
)
def test_the_compiled_right_hand_side_is_the_laws_own(crane, cycle, resolver, monkeypatch):
    """The core's adaptive loop gives the same motions on a built-in law's compiled right-hand
    side as on the law's Python one (`Law.stage`, what a law of your own runs on). The segment
    is straight at constant speed: the compiled loop reads its ẏ_d as one constant, the Python
    one from `Segment.velocity_at` at each stage.

    On the grid they agree to rounding. Sampled at the steps, the same steps are taken and the
    same motions stopped, but a step's size follows its error estimate, a difference of slopes
    some 1e-8 of their size: rounding in the slopes moves the steps by about 1e-9 of their
    size, and the samples with them."""
    segment = cycle["3-1"]
    starts = reachable_starts(crane, segment, np.linspace(0.05, 1.05, 9))

    def motions():
        return [
            simulate(crane, resolver, segment, starts, sparse=sparse, stop_past=sparse)
            for sparse in (False, True)
        ]

    compiled = motions()
    monkeypatch.setattr(integrate, "compiled_rates", lambda robot, law: None)
    for ours, python in zip(compiled, motions()):
        np.testing.assert_array_equal(ours.steps.rows, python.steps.rows)
        np.testing.assert_array_equal(ours.stopped, python.stopped)
        assert ours.t.shape == python.t.shape
        close = 1e-7 if ours.sparse else 1e-12
        for name in ("t", "q", "x", "x_dot"):  # relative to each one's scale: ẋ passes zero
            a, b = getattr(ours, name), getattr(python, name)
            np.testing.assert_allclose(a, b, rtol=0, atol=close * np.abs(b).max())
    assert compiled[1].stopped.any()  # the loop stopped motions past their strokes


@pytest.mark.parametrize(
    "case", ["velocity", "inertia", "pull", "closed loop", "called back", "held"]
)
def test_the_loop_s_inner_stages_are_the_recorded_ones_to_the_last_bit(crane, cycle, case):
    """The compiled loop builds the evaluation's arrays only at the last stage of a step, and
    only where it keeps the ends (``keep``, a sparse motion's samples); it derives the other
    stages without them. Both ways give the same slopes bit for bit, so keeping the ends moves
    no step and stops no other motion, whatever the law reads of a state: each weight (I, M_H),
    the null-space pull (which reads x), the closed loop on a straight segment (y), ẏ called
    back from Python with y, and a held law (its rates called back with x); the loop stops
    motions past the strokes (x) in each."""
    segment, values, gain = cycle["3-1"], np.linspace(0.05, 1.05, 9), 0.0
    resolver = {"inertia": ENERGY.resolver, "pull": GradientProjection()}.get(case)
    if case in ("closed loop", "called back"):
        gain = 5.0
    if case == "held":
        segment, values, gain = cycle["1-2"], np.linspace(0.7, 1.0, 4), 1.0
        nodes = np.linspace(0.0, segment.duration, 9)
        resolver = HeldReference(
            2, nodes, 0.9 + 0.15 * np.sin(2 * np.pi * nodes / segment.duration)
        )
    law = integrate.Law(crane, resolver or VELOCITY.resolver, segment, gain, None)
    velocity = law.velocity if case == "called back" else law.loop_velocity
    assert law.compiled is not None
    assert isinstance(velocity, tuple) == (case in ("closed loop", "held"))  # else ẏ_d or a call
    starts = reachable_starts(crane, segment, values)
    first = law(np.zeros(len(starts)), starts)
    strokes = np.array(
        [[crane.actuators[a].lower, crane.actuators[a].upper] for a in crane.actuators.names]
    )
    fixed = (integrate.TOLERANCE, *integrate.TABLEAU, *strokes.T, 1e-5, True)
    lean, kept = (
        integrate._core.dormand_prince(
            law.compiled,
            velocity,
            starts,
            first.q_dot,
            first.bad,
            segment.duration,
            segment.breaks,
            SAME_TIME,
            *fixed,
            keep,
            integrate.MAX_STEPS,
            integrate.MAX_SINGULAR,
        )
        for keep in (False, True)
    )
    assert not lean[-1] and kept[-1]  # only the second kept the ends' records
    assert np.unique(lean[0]).size == len(starts)  # every motion took steps
    for a, b in zip(lean[:7], kept[:7]):  # rows, t0, h, q0, slopes, failed, stopped
        np.testing.assert_array_equal(a, b)
    if case == "velocity":
        assert kept[6].any()  # the loop stopped motions past their strokes


def test_the_closed_loop_on_a_straight_segment_runs_in_the_core(crane, cycle, monkeypatch):
    """With feedback K on a straight segment at constant speed, the core's loop adds
    K (y_d(0) + ẏ_d t − y) itself, calling back to the path at no stage, and gives the motions
    those calls give (`Law.velocity`, y_d(t) from the path), on the grid to rounding."""
    segment = cycle["2-3"]
    starts = reachable_starts(crane, segment, np.linspace(0.2, 0.9, 5))
    calls = []
    velocity = integrate.Law.velocity
    monkeypatch.setattr(
        integrate.Law, "velocity", lambda self, t, y: calls.append(t) or velocity(self, t, y)
    )

    def motion():
        return simulate(crane, VELOCITY.resolver, segment, starts, gain=2.0)

    compiled = motion()
    assert not calls
    monkeypatch.setattr(integrate.Law, "loop_velocity", property(lambda self: self.velocity))
    called = motion()
    assert calls
    for name in ("t", "q", "x", "x_dot"):
        a, b = getattr(compiled, name), getattr(called, name)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())


def test_a_held_law_runs_in_the_compiled_loop_as_in_python(crane, cycle, monkeypatch):
    """A periodic plan's law (`HeldReference`: x3 follows r(t), the others the task, with
    feedback on both) integrates in the core's loop, its held rates called once per batch, to
    the motions its Python right-hand side gives: on the grid to rounding, and its held
    actuator, from starts off the plan, on r(t) once the feedback has settled."""
    segment = cycle["1-2"]
    starts = reachable_starts(crane, segment, np.linspace(0.7, 1.0, 4))
    nodes = np.linspace(0.0, segment.duration, 9)
    plan = 0.9 + 0.15 * np.sin(2 * np.pi * nodes / segment.duration)
    law = HeldReference(2, nodes, plan)
    assert integrate.compiled_rates(crane, law) is not None

    def motion():
        return simulate(crane, law, segment, starts, gain=1.0)

    stages = []
    stage = integrate.Law.stage
    monkeypatch.setattr(
        integrate.Law, "stage", lambda self, t, q: stages.append(t) or stage(self, t, q)
    )
    compiled = motion()
    assert not stages  # no stage fell back to Python
    monkeypatch.setattr(integrate, "compiled_rates", lambda robot, law: None)
    python = motion()
    assert stages
    for name in ("t", "q", "x", "x_dot"):
        a, b = getattr(compiled, name), getattr(python, name)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())
    settled = compiled.t > 10 / law.gain  # ten time constants of the held feedback
    lag = np.abs(compiled.x[:, :, 2] - law.reference(compiled.t)[..., 0])[settled]
    assert lag.max() < 1e-5, lag.max()
    assert np.ptp(compiled.x[:, 0, 2]) > 0.05  # the starts were not on the plan alike


def test_a_held_law_of_your_own_runs_in_python(crane):
    """A subclass that answers `resolve_at` itself is its own law: the core does not run it."""

    class Mine(HeldReference):
        def resolve_at(self, space, y_dot, t):
            return super().resolve_at(space, y_dot, t)

    nodes = np.linspace(0.0, 1.0, 5)
    assert integrate.compiled_rates(crane, Mine(2, nodes, np.full(5, 0.9))) is None


def test_a_path_that_evaluates_the_robot_within_a_step_changes_no_solve(crane, cycle, monkeypatch):
    """The compiled loop solves each state on the factors of A its own evaluation kept. A path
    whose ẏ_d is read by calling Python at each stage (here a trapezoidal profile) may evaluate
    the same robot in between, on a batch of another size (a path of your own may): the
    motions are the same, bit for bit."""
    segment = replace(cycle["1-2"], profile="trapezoidal", acceleration=0.5)
    starts = reachable_starts(crane, segment, np.linspace(0.2, 0.9, 5))
    elsewhere = reachable_starts(crane, cycle["3-1"], np.linspace(0.1, 0.9, 7))
    assert integrate.compiled_rates(crane, VELOCITY.resolver) is not None  # the compiled loop
    assert len(elsewhere) >= len(starts)  # would overwrite every state's factors if shared
    alone = simulate(crane, VELOCITY.resolver, segment, starts)
    velocity = integrate.Law.velocity
    calls = []

    def evaluating(law, t, y):
        calls.append(actuator_space(crane, elsewhere).J_H)
        return velocity(law, t, y)

    monkeypatch.setattr(integrate.Law, "velocity", evaluating)
    between = simulate(crane, VELOCITY.resolver, segment, starts)
    assert len(calls) > 10  # the loop called the path back at its stages
    for name in ("t", "q", "x", "x_dot"):
        np.testing.assert_array_equal(getattr(between, name), getattr(alone, name))


class Unweighted(Resolver):
    """min ẋᵀẋ as a law of one's own: its motions run on the Python right-hand side."""

    def weight(self, space):
        return np.broadcast_to(np.eye(space.robot.n), space.A.shape)


@pytest.mark.parametrize("method", ["adaptive", "rk4"])
def test_a_start_whose_task_velocity_is_not_finite_is_frozen_on_either_right_hand_side(
    crane, cycle, method
):
    """In closed loop ẏ = ẏ_d + K (y_d − y): from a start with the telescope out 1e308 m, y and
    so ẏ are not finite. That start fails and the other runs on, whether the law is compiled or
    one's own (the Python right-hand side), to the same motion."""
    starts = np.array([[1.6, 1.0, 0.5], [1.6, 1.0, 1e308]])
    motions = [
        simulate(crane, law, cycle["1-2"], starts, method=method, gain=5.0)
        for law in (VELOCITY.resolver, Unweighted())
    ]
    for motion in motions:
        assert motion.failed.tolist() == [False, True]
    compiled, python = (motion.q[0, : motion.counts[0]] for motion in motions)
    np.testing.assert_allclose(python, compiled, rtol=0, atol=1e-9)


def _bent_arm(folder):
    """A planar 3R arm in the x-z plane whose elbow and wrist are bent in the URDF itself
    (their origins turned by 1.2 and 1.0 rad), driven directly: q = 0 is a regular configuration
    well inside its limits."""
    links, joints = ['<link name="base"/>'], []
    for i, (length, turn) in enumerate([(1.0, 0.0), (0.8, -1.2), (0.5, -1.0)], start=1):
        parent = "base" if i == 1 else f"l{i - 1}"
        offset = 0.0 if i == 1 else [1.0, 0.8][i - 2]
        links.append(
            f'<link name="l{i}"><inertial><origin xyz="{length / 2} 0 0"/><mass value="5"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.4" iyz="0" izz="0.4"/></inertial></link>'
        )
        joints.append(
            f'<joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>'
            f'<origin xyz="{offset} 0 0" rpy="0 {turn} 0"/><axis xyz="0 -1 0"/>'
            '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        )
    tool = '<joint name="tj" type="fixed"><parent link="l3"/><child link="tool"/>'
    tool += '<origin xyz="0.5 0 0"/></joint><link name="tool"/>'
    body = "".join(links + joints) + tool
    (folder / "arm.urdf").write_text(f'<?xml version="1.0"?><robot name="bent">{body}</robot>')
    actuators = "".join(
        f'[actuators.a{i}]\nkind = "Identity"\njoint = "j{i}"\nstroke = [-3, 3]\n'
        for i in (1, 2, 3)
    )
    toml = folder / "robot.toml"
    toml.write_text(f'urdf = "arm.urdf"\ntool_frame = "tool"\ntask_axes = "xz"\n{actuators}')
    return load_robot(toml)


def test_a_start_at_q_zero_is_integrated_as_one_beside_it(tmp_path):
    """The first step's size scales with ‖q‖; at q = 0 exactly it was 0, and the motion from a
    regular start was frozen and flagged as failed. It now moves as from q = 1e-7 beside it."""
    arm = _bent_arm(tmp_path)
    y_0 = actuator_space(arm, np.zeros(3)).y[0]
    segment = Segment("l", y_0, y_0 + np.array([-0.3, -0.2]), 0.5)
    at_zero, beside = (
        simulate(arm, VELOCITY.resolver, segment, start)
        for start in (np.zeros(3), np.array([0.0, 0.0, 1e-7]))
    )
    assert not at_zero.failed[0] and not beside.failed[0]
    assert at_zero.max_tracking_error[0] < 1e-5
    np.testing.assert_allclose(at_zero.q[0, -1], beside.q[0, -1], atol=1e-5)


def test_a_trapezoidal_segment_is_integrated_to_its_tolerance_across_its_ramp_ends(crane):
    """The speed profile's acceleration jumps where its ramps end (0.5 s) and begin (5.0 s): a
    step that straddled one was accurate only to its order there, and the tool left the path by
    0.46 mm, the strokes by 6.9e-5 m, more than the allowance a search's sparse samples are read
    with (30 × the tolerance, 3e-5 m). Steps now end at those times, and both errors, against a
    motion at 1e-10, are within it."""
    trapezoid = Segment(
        "t", np.array([3.5, -0.5]), np.array([1.0, -0.5]), 0.5, None, "trapezoidal", 1.0
    )
    np.testing.assert_array_equal(trapezoid.breaks, [0.5, 5.0])
    _, start = default_start(crane, trapezoid)
    motion = simulate(crane, VELOCITY.resolver, trapezoid, start)
    ends = motion.steps.t0 + motion.steps.h
    assert np.abs(ends[:, None] - trapezoid.breaks).min(axis=0).max() < 1e-12
    reference = simulate(crane, VELOCITY.resolver, trapezoid, start, tolerance=1e-10)
    allowance = integrate.ALLOWANCE * integrate.TOLERANCE
    assert motion.max_tracking_error[0] < allowance
    assert np.abs(motion.x - reference.x).max() < allowance


def test_a_polyline_is_integrated_to_its_tolerance_across_its_corners(crane):
    """A recorded path's corners are where ẏ_d jumps: a step across one left the tool 2.2 mm
    off the path and the strokes 4.5e-4 m, fifteen times the allowance. Steps now end at the
    corners, the last stage of such a step reads the piece it integrated and the next step
    starts from the law's slope on the next piece: the strokes, against a motion at 1e-10, are
    within the allowance, and the tool within a tenth of a millimetre of the path."""
    corners = np.array([[3.5, -0.5], [3.0, 0.5], [2.5, -0.2], [2.0, 0.8], [1.5, 0.0]])
    path = Segment.along("recorded", Polyline(corners), 0.5)
    np.testing.assert_allclose(path.progress(path.breaks)[0], path.shape.cumulative[1:-1])
    _, start = default_start(crane, path)
    motion = simulate(crane, VELOCITY.resolver, path, start)
    ends = motion.steps.t0 + motion.steps.h
    assert np.abs(ends[:, None] - path.breaks).min(axis=0).max() < 1e-12
    reference = simulate(crane, VELOCITY.resolver, path, start, tolerance=1e-10)
    assert motion.max_tracking_error[0] < 1e-4
    assert np.abs(motion.x - reference.x).max() < integrate.ALLOWANCE * integrate.TOLERANCE


def test_every_stage_at_the_end_of_a_step_onto_a_corner_reads_the_piece_it_integrated(crane):
    """Dormand-Prince has two stages at a step's end (c = 1). Where the step ends on a corner,
    the one before the last read the next piece's ẏ_d: the error estimate saw the jump, steps
    shrank towards every corner (twice the steps) and, at the reports' tolerance, 3 of 29
    starts on a closed three-corner path failed where the steps fell below 1e-9 of the
    duration. Every start now runs to the end, each step ends on or before a corner, and the
    motion tracks the path to the reports' precision."""
    path = Segment.along(
        "triangle", Polyline([[3.5, -0.5], [1.0, -0.5], [2.25, 3.0], [3.5, -0.5]]), 0.5
    )
    found = inverse_kinematics(crane, path.start, ["x3"], np.linspace(0.80, 1.09, 30)[:, None])
    motion = simulate(
        crane, VELOCITY.resolver, path, found.q[found.reached], tolerance=REPORT_TOLERANCE
    )
    assert found.reached.sum() == 29 and not motion.failed.any()
    assert motion.max_tracking_error.max() < 1e-6


def test_accelerations_and_forces_do_not_grow_at_a_corner_as_the_samples_get_closer(crane):
    """Turning a polyline's corner at speed ẋ jumps: differences of ẋ across the corner made ẍ,
    the forces and the load pressures there grow as 1/Δt (353 bar at 10 ms, 2,775 at 1 ms on a
    forwarder crane). ẍ is taken within each piece between corners now: the largest ẍ and
    load pressure of the motion sampled every 10 ms and every 2.5 ms agree to 2 %, and beside
    the corners ẍ is the motion's own (against the finer grid, to 1e-3 of the largest)."""
    corners = np.array([[3.5, -0.5], [3.0, 0.5], [2.5, -0.2]])
    path = Segment.along("recorded", Polyline(corners), 0.5)
    _, start = default_start(crane, path)
    coarse, fine = (
        simulate(crane, ENERGY.resolver, path, start, step, tolerance=1e-10)
        for step in (0.01, 0.0025)
    )
    largest = np.abs(fine.x_ddot).max()
    assert np.abs(coarse.x_ddot).max() == pytest.approx(largest, rel=0.02)
    load = [m.flows.load[0].max() for m in (coarse, fine)]
    assert load[0] == pytest.approx(load[1], rel=0.02)
    far = np.abs(coarse.t[0][:, None] - path.breaks).min(axis=1) > 0.05
    on_fine = np.interp(coarse.t[0][far], fine.t[0], fine.x_ddot[0, :, 1])
    assert np.abs(coarse.x_ddot[0, far, 1] - on_fine).max() < 1e-3 * largest


def test_the_time_at_an_arc_length_inverts_the_speed_profile():
    """`Segment.time_at` against `progress` on both ramps and between them: s(t(s)) = s."""
    path = Segment("t", np.array([3.5, -0.5]), np.array([1.0, -0.5]), 0.5, None, "trapezoidal", 1.0)
    s = np.linspace(0.0, path.shape.length, 41)
    np.testing.assert_allclose(path.progress(path.time_at(s))[0], s, atol=1e-12)
    steady = Segment("c", np.array([3.5, -0.5]), np.array([1.0, -0.5]), 0.5)
    np.testing.assert_allclose(steady.time_at(s), s / 0.5)


def test_a_motion_whose_path_leaves_the_reach_fails_at_its_edge_once_it_crawls_there():
    """The slewing 3R arm (links 1, 0.8 and 0.5 m: it reaches 2.3 m at most) from the closed
    form's elbow up at (2, 0) m, along x at 0.2 m/s to 2.6 m: the path leaves the reach at
    t = 1.5 s. There the law holds the tool at the edge, stretched, J_H singular, and chatters;
    its steps shrank to a few microseconds and ran on, each kept, until the process ran out of
    memory (a random line of a search did so at 24 GB), then until `MAX_STEPS` had been tried
    (a sweep of 200 starts along a line out of the excavator's reach took 15 s and 5.3 GB). The
    motion is now frozen as failed once `MAX_SINGULAR` accepted steps in a row have ended where
    the law damps its solve, J_H singular: at the edge, just past 1.5 s, after 84 steps; a sweep
    of 200 starts keeps 44 steps a start."""
    robot = load_robot(Path(__file__).parent / "data" / "slewing3r" / "robot.toml")
    segment = Segment("out", np.array([2.0, 0.0]), np.array([2.6, 0.0]), 0.2)
    start = slew_held_configuration(0.0, 1, segment.start)[None]
    motion = simulate(robot, VELOCITY.resolver, segment, start, sparse=True)
    assert motion.failed[0]
    assert len(motion.steps.rows) < 3 * integrate.MAX_SINGULAR
    frozen = (motion.steps.t0 + motion.steps.h).max()
    assert 1.5 <= frozen < 1.6
    assert abs(np.linalg.norm(motion.y[0, -1]) - 2.3) < 1e-6  # stretched at the edge
    sigma = np.linalg.svd(actuator_space(robot, motion.q[0, -1]).J_H[0], compute_uv=False)
    assert sigma[-1] / sigma[0] < np.sqrt(SINGULAR_RATIO)  # at m = 2, where G = J_H J_Hᵀ is damped
    sweep = improved_start(robot, segment, VELOCITY, "x3", samples=200, method="sweep")
    assert not sweep.feasible
    assert sum(len(b.steps.rows) for b in sweep.batches) < 200 * 3 * integrate.MAX_SINGULAR


def test_at_three_task_coordinates_a_motion_that_leaves_the_reach_fails_at_its_edge_too():
    """The Panda (m = 3, seven joints driven directly) from mid-range, along the line from its
    shoulder (joint 2, 0.333 m up) through the tool, outward 1.5 m at 0.2 m/s: the line leaves
    the reach about 0.95 m from the shoulder. At m ≥ 3 the law's determinant test of G = J_H
    J_Hᵀ is a sufficient condition only, so the rule that fails a crawling motion reads whether
    the law damped (λ² > 0), not that test. Without the rule the motion tried `MAX_STEPS` steps
    and kept 1,959 of them; it is now frozen after 89, stretched (σ_min / σ_max of J_H 6e-7),
    the tool still on the line."""
    with pytest.warns(UserWarning, match="driven directly"):
        robot = load_robot("panda")
    start = (robot.lower + robot.upper) / 2
    tool = actuator_space(robot, start).y[0]
    shoulder = np.array([0.0, 0.0, 0.333])
    out = (tool - shoulder) / np.linalg.norm(tool - shoulder)
    segment = Segment("out", tool, tool + 1.5 * out, 0.2)
    motion = simulate(robot, VELOCITY.resolver, segment, start[None], sparse=True)
    assert motion.failed[0]
    assert len(motion.steps.rows) < 3 * integrate.MAX_SINGULAR
    end = motion.y[0, -1]
    reach = np.linalg.norm(end - shoulder)
    assert 0.9 < reach < 1.0  # as far as it came: it chattered at the edge, stretched
    assert np.linalg.norm(motion.y[0] - shoulder, axis=1).max() - reach < 1e-9
    assert np.linalg.norm(np.cross(end - tool, out)) < 1e-6  # on the line
    sigma = np.linalg.svd(actuator_space(robot, motion.q[0, -1]).J_H[0], compute_uv=False)
    assert sigma[-1] / sigma[0] < np.sqrt(SINGULAR_RATIO)


def test_a_motion_that_touches_the_edge_of_the_reach_and_turns_back_passes():
    """The slewing 3R arm out to its reach, 2.3 m, and back: stretched at the corner, J_H is
    singular there (σ_min / σ_max 7e-5) and the law damps a step or two, fewer than the
    `MAX_SINGULAR` in a row that fail a motion crawling along the edge. The motion runs to its
    end and keeps its path to 1e-6 m."""
    robot = load_robot(Path(__file__).parent / "data" / "slewing3r" / "robot.toml")
    points = np.array([[2.0, 0.0], [2.3, 0.0], [2.0, 0.3]])
    segment = Segment.along("touch", Polyline(points), 0.2)
    start = slew_held_configuration(0.0, 1, segment.start)[None]
    motion = simulate(robot, VELOCITY.resolver, segment, start, sparse=True)
    assert not motion.failed[0]
    sigma = np.linalg.svd(actuator_space(robot, motion.q[0]).J_H, compute_uv=False)
    assert (sigma[:, -1] / sigma[:, 0]).min() < np.sqrt(SINGULAR_RATIO)  # it did pass one
    np.testing.assert_allclose(motion.y[0, -1], segment.end, atol=1e-6)


def test_a_recorded_path_of_many_points_is_not_cut_short_by_the_step_cap(crane):
    """No step crosses a break, and a recorded path has one at each inner point, so a polyline
    of 2,500 points along a straight line needs 2,500 steps at least, more than `MAX_STEPS`:
    every start failed, as if its steps had shrunk to a crawl. The cap counts the steps beyond
    one per break: the motion runs to its end, a step ending on every point, and its strokes are
    those along the line as one piece, within the sparse samples' allowance."""
    line = np.linspace([3.5, -0.5], [2.0, 0.8], 2_500)
    path = Segment.along("recorded", Polyline(line), 0.5)
    assert len(path.breaks) > integrate.MAX_STEPS
    _, start = default_start(crane, path)
    motion = simulate(crane, VELOCITY.resolver, path, start, sparse=True)
    assert not motion.failed[0]
    ends = motion.steps.t0 + motion.steps.h
    assert abs(ends.max() - path.duration) < 1e-9 * path.duration
    assert np.abs(ends[:, None] - path.breaks).min(axis=0).max() < 1e-12
    straight = Segment("straight", line[0], line[-1], 0.5)
    whole = simulate(crane, VELOCITY.resolver, straight, start, tolerance=1e-10)
    assert np.abs(motion.on_grid().x - whole.x).max() < integrate.ALLOWANCE * integrate.TOLERANCE


def test_an_integral_over_steps_and_their_midpoints_is_exact_for_a_cubic():
    """Simpson's rule on each step of uneven length, from samples at the steps' ends and
    middles with the last repeated (a shorter motion's padding), integrates a cubic exactly;
    the trapezoids between the same samples do not."""
    ends = np.array([0.0, 0.3, 1.0, 2.5])
    t = np.sort(np.concatenate([ends, (ends[1:] + ends[:-1]) / 2, [2.5, 2.5]]))[None]
    cubic = 1 + 2 * t - 3 * t**2 + 0.5 * t**3
    exact = 2.5 + 2.5**2 - 2.5**3 + 0.125 * 2.5**4
    assert integral(t, cubic, np.empty(0))[0] == pytest.approx(exact, rel=1e-14)
    assert abs(integral(t, cubic)[0] / exact - 1) > 1e-2


def test_a_step_from_a_jump_is_integrated_from_its_middle_alone():
    """Where ẏ_d jumps (a polyline's corner), the sample is the piece before's: f = t² up to
    t = 1 s, 5 + t after it. Simpson's rule on the first step and the midpoint rule on the
    step from the jump, exact for those, give ∫ f dt over [0, 2.5] s; Simpson's rule there,
    from the value before the jump, misses it by 12 %."""
    t = np.array([[0.0, 0.5, 1.0, 1.75, 2.5]])
    f = np.where(t <= 1.0, t**2, 5 + t)
    exact = 1 / 3 + 5 * 1.5 + (2.5**2 - 1) / 2
    assert integral(t, f, np.array([1.0]))[0] == pytest.approx(exact, rel=1e-14)
    assert abs(integral(t, f, np.empty(0))[0] / exact - 1) > 0.1


def test_breaks_a_rounding_error_apart_are_one_and_hide_no_corner():
    """A trapezoidal segment too short to reach its speed ends its ramp up where its ramp down
    begins, and its two ramp ends fell a rounding error apart, both kept as breaks. The probes
    either side of every break, a billionth of the shortest time between two breaks, then read
    the very time of the cycle's corners, and found none there (the shortest duration ran
    straight through them). The twins are one break, and each break is probed by the time to its
    own nearest neighbour."""
    short = Segment(
        "short", np.array([2.0, 0.0]), np.array([2.1, 0.0]), 5.0, None, "trapezoidal", 1.0
    )
    up = Segment("up", short.end, np.array([2.1, 2.0]), 0.5)
    back = Segment("back", up.end, short.start, 0.5)
    cycle = Chain("triangle", (short, up, back))
    np.testing.assert_allclose(short.breaks, [short.duration / 2], rtol=1e-15)
    turns = cycle.offsets[1:-1]
    np.testing.assert_allclose(cycle.breaks, [short.duration / 2, *turns], rtol=1e-15)
    np.testing.assert_allclose(corners(cycle), turns)
    np.testing.assert_allclose(jumps(cycle), turns)
    # two points 2 nm apart, a far corner beside them: each break probed by its own neighbours
    points = np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.5 + 2e-9, 0.5], [1.0, 1.0]])
    near = Segment.along("near", Polyline(points), 0.1)
    np.testing.assert_allclose(corners(near), near.breaks)
    np.testing.assert_allclose(jumps(near), near.breaks)


def test_a_path_jumps_at_its_corners_turned_at_speed_not_at_its_ramp_ends(crane):
    """Steps end at every break of a path, but ẏ_d jumps at a polyline's corners alone: at a
    ramp's end only its rate does, and there Simpson's rule is kept (the midpoint rule there
    missed ∫ ẋᵀẋ dt on a ramped line by 0.9 %); the estimate on the steps is the integral on a
    1 ms grid at the reports' tolerance to 1e-3."""
    corners = np.array([[3.5, -0.5], [1.0, -0.5], [2.25, 3.0], [3.5, -0.5]])
    turning = Segment.along("triangle", Polyline(corners), 0.5, "trapezoidal", 1.0)
    np.testing.assert_allclose(jumps(turning), turning.breaks[1:-1])
    assert len(turning.breaks) == 4
    ramped = Segment("ramped", corners[0], corners[1], 0.5, None, "trapezoidal", 1.0)
    assert len(ramped.breaks) == 2 and len(jumps(ramped)) == 0
    travel = replace(VELOCITY, name="travel", reduction="integral")
    starts = reachable_starts(crane, ramped, [0.9, 1.0, 1.09])
    sparse = simulate(crane, travel.resolver, ramped, starts, sparse=True)
    grid = simulate(crane, travel.resolver, ramped, starts, 1e-3, tolerance=REPORT_TOLERANCE)
    np.testing.assert_allclose(sparse.score(travel), grid.score(travel), rtol=1e-3)


def test_a_corner_where_the_path_comes_to_rest_is_no_jump(crane, cycle):
    """The paper's cycle with trapezoidal profiles stops at each corner: ẏ_d is 0 either side,
    only its direction turns, and the time scaling stops there (`corners`), but ẏ_d does not
    jump. Measured against the speeds either side, which are tiny there, the turn counted as a
    jump, and the step after it took the midpoint rule: ∫ ẋᵀẋ dt on the steps missed the
    integral on a 1 ms grid at the reports' tolerance by 0.31 %. Against the path's peak speed
    it is no jump, and Simpson's rule there misses by 8e-5, within the 1e-3 held for the other
    estimates on steps."""
    segments = tuple(replace(s, profile="trapezoidal", acceleration=0.5) for s in cycle.segments)
    resting = Chain("resting", segments)
    turns = resting.offsets[1:-1]
    np.testing.assert_allclose(corners(resting), turns)
    assert len(jumps(resting)) == 0
    travel = replace(VELOCITY, name="travel", reduction="integral")
    starts = reachable_starts(crane, resting, [0.3, 0.6, 0.9])
    sparse = simulate_path(crane, travel.resolver, resting, starts, sparse=True)
    grid = simulate_path(crane, travel.resolver, resting, starts, 1e-3, tolerance=REPORT_TOLERANCE)
    np.testing.assert_allclose(sparse.score(travel), grid.score(travel), rtol=1e-3)


def test_an_integral_objective_on_a_motions_steps_is_its_integral_on_a_fine_grid():
    """∫ q̇ᵀq̇ dt of motions of a 4R arm with two held actuators, on their three adaptive steps
    over 2.6 s and their midpoints, is the integral on a 1 ms grid at the reports' tolerance
    to 1e-3 (5e-5 seen); the trapezoids between those samples miss by 1.5-1.9 %, more than the
    starts' integrals differ by near the best (the improved start ranks its samples so)."""
    robot = load_robot(PLANAR / "robot.toml")
    segment = WorkCycle.from_toml(PLANAR / "two_held.toml", dimension=robot.m)["a-b"]
    values = np.array([[-1.1576, 0.3643], [-1.0, 0.5], [-1.1, 0.3]])
    found = inverse_kinematics(robot, segment.start, ["x1", "x3"], values)
    assert found.reached.all()
    sparse = simulate(robot, SQUARED.resolver, segment, found.q, sparse=True)
    grid = simulate(robot, SQUARED.resolver, segment, found.q, 1e-3, tolerance=REPORT_TOLERANCE)
    fine = grid.score(SQUARED)
    np.testing.assert_allclose(sparse.score(SQUARED), fine, rtol=1e-3)
    assert np.all(np.abs(integral(sparse.t, sparse.values(SQUARED)) / fine - 1) > 1e-2)


def test_a_grid_time_a_rounding_error_past_a_steps_end_is_sampled_once(crane):
    """A step here ends at 1.4 s, and the grid's time there is 1.4000000000000001 s: the step
    took it within its margin, and so did the next step, from just below it. That motion had
    one sample too many, every later one a slot late and the last dropped: its tool 5 mm
    behind the path (0.5 m/s × 10 ms). Each grid time is now sampled once, by one step, and the
    motion tracks its path."""
    path = Segment(
        "ramped", np.array([3.5, -0.5]), np.array([1.0, -0.5]), 0.5, None, "trapezoidal", 1.0
    )
    found = inverse_kinematics(crane, path.start, ["x3"], np.array([[0.9845454545454546]]))
    motion = simulate(crane, VELOCITY.resolver, path, found.q)
    grid = integrate.time_grid(path)
    ends = motion.steps.t0 + motion.steps.h
    near = np.abs(ends[:, None] - grid).min(axis=0)
    assert np.any((near > 0) & (near < 1e-12 * grid[-1]))  # a step's end at a grid time, rounded
    times = motion.steps.dense(grid)[1]
    assert len(times) == len(grid) - 1 and np.all(np.diff(times) > 0)
    assert motion.max_tracking_error[0] < 1e-4
