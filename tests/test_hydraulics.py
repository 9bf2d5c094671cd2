"""The hydraulic circuit: hand calculations, the power balance, the energy chain, the objectives
and the energy bound on the paper's crane."""

import dataclasses
import itertools
import json
import math
import pickle
import re
from pathlib import Path

import numpy as np
import pytest
from commands import run_cli
from joint_space import mechanical_energy
from sampling import random_configurations

from redundancy import load_robot
from redundancy.errors import (
    InvalidInputError,
    RedundancyError,
    RobotDescriptionError,
    UnreachableError,
)
from redundancy.model.hydraulics import BAR, LITRES_PER_MINUTE, circuit_from_table
from redundancy.planning.integral_optimum import (
    EXACT,
    Tables,
    _nodes,
    energy_optimum,
    integral_optimum,
)
from redundancy.planning.integrate import MIN_INTERVALS, simulate
from redundancy.planning.refinement import CONVERGED
from redundancy.planning.starts import default_start, improved_start
from redundancy.planning.tasks import Arc, Line, Polyline, Segment, WorkCycle, corners
from redundancy.planning.time_scaling import shortest_duration
from redundancy.resolution.laws import MinFlow
from redundancy.resolution.limits import TOLERANCE, Limits, hydraulic_values
from redundancy.resolution.objectives import CP_ENERGY, ENERGY, FLOW, LS_ENERGY, VELOCITY
from redundancy.resolution.state import actuator_space
from redundancy.study import peers
from redundancy.study.peers import fixed_start_run
from redundancy.study.study import BASELINES, run_study
from redundancy.viz.tables import hydraulic_table, study_table


@pytest.fixture(scope="module")
def cycle(crane):
    return WorkCycle.from_toml(crane.task_file, dimension=crane.m)


@pytest.fixture(scope="module")
def motions(crane, cycle):
    """Each paper segment's baselines from the default start, on a 3 ms grid, integrated to
    1e-10 a step: the power balance's central differences then see the grid's O(h²) alone,
    as they do on the fixed-step method's 3 ms steps, at an eighth of its cost."""
    found = {}
    for segment in cycle.segments:
        start = default_start(crane, segment, ["x3"])[1][None]
        found[segment.name] = [
            simulate(crane, resolver, segment, start, 0.003, tolerance=1e-10)
            for _, resolver in BASELINES
        ]
    return found


def test_the_crane_declares_its_cylinders(crane):
    circuit = crane.circuit()
    assert circuit.names == ("x1", "x2", "x3")
    lift = circuit.cylinders[0]
    assert lift.piston_area == pytest.approx(math.pi * 0.080**2 / 4, rel=1e-15)
    assert lift.rod_side_area == pytest.approx(math.pi * (0.080**2 - 0.045**2) / 4, rel=1e-15)
    assert circuit.supply.name == "LS"
    assert circuit.relief == pytest.approx(210e5)
    assert circuit.pump_flow == pytest.approx(100 / 60000)


def test_flows_and_pressures_by_hand(crane):
    """The meter-in model against numbers worked out by hand for the lift cylinder (80/45 mm,
    p_T = 2 bar) and the fold cylinder (70/40 mm)."""
    circuit = crane.circuit()
    a_lift, b_lift = 5.026548245743669e-3, 3.436116964863837e-3  # π 0.08²/4, π(0.08²−0.045²)/4
    a_fold, b_fold = 3.848451000647497e-3, 2.591813939211580e-3  # π 0.07²/4, π(0.07²−0.04²)/4
    x_dot = np.array([[0.1, -0.05, 0.0], [0.0, 0.0, 0.0], [-0.1, 0.02, 0.0]])
    forces = np.array([[20e3, -5e3, 1e3], [20e3, 8e3, 0.0], [20e3, 8e3, 0.0]])
    flows = circuit.flows(x_dot, forces)
    # extending lift: Q = A_A ẋ, p_L = (F + p_T A_B)/A_A
    assert flows.flow[0, 0] == pytest.approx(a_lift * 0.1, rel=1e-12)
    assert flows.load[0, 0] == pytest.approx((20e3 + 2e5 * b_lift) / a_lift, rel=1e-12)
    assert flows.load[0, 0] / BAR == pytest.approx(41.155, abs=1e-3)
    # retracting fold against a pulling load: Q = A_B |ẋ|, p_L = (−F + p_T A_A)/A_B
    assert flows.flow[0, 1] == pytest.approx(b_fold * 0.05, rel=1e-12)
    assert flows.load[0, 1] == pytest.approx((5e3 + 2e5 * a_fold) / b_fold, rel=1e-12)
    assert not flows.overrunning[0].any()
    # LS: the highest moving load plus 20 bar; the still telescope does not count
    assert flows.pump_pressure(circuit.load_sensing)[0] == pytest.approx(
        flows.load[0, 0] + 20e5, rel=1e-12
    )
    assert flows.pump_flow[0] / LITRES_PER_MINUTE == pytest.approx(
        (a_lift * 0.1 + b_fold * 0.05) * 60000, rel=1e-12
    )
    # holding still: no flow, no power, the static pressure of the extending branch
    assert flows.pump_flow[1] == 0 and flows.power(circuit.load_sensing)[1] == 0
    assert flows.load[1, 1] == pytest.approx((8e3 + 2e5 * b_fold) / a_fold, rel=1e-12)
    # lowering the lift under its load overruns: p_L is negative, counted at p_T and flagged
    assert (-20e3 + 2e5 * a_lift) / b_lift < 0
    assert flows.load[2, 0] == pytest.approx(2e5) and flows.overrunning[2, 0]
    assert flows.power(circuit.constant_pressure)[2] == pytest.approx(
        180e5 * (b_lift * 0.1 + a_fold * 0.02), rel=1e-12
    )
    useful = flows.load[0, 0] * a_lift * 0.1 + flows.load[0, 1] * b_fold * 0.05
    assert flows.useful_power[0] == pytest.approx(useful, rel=1e-12)
    assert flows.loss(circuit.load_sensing)[0] == pytest.approx(
        flows.power(circuit.load_sensing)[0] - useful, rel=1e-12
    )


def test_static_pressures_hold_the_crane(crane):
    """Holding still, each cylinder's pressure is its gravity force (A⁻ᵀ G from Pinocchio)
    over its piston area, plus the rod side's tank pressure."""
    circuit = crane.circuit()
    q = random_configurations(crane, 5, seed=41, margin=0.05)
    space = actuator_space(crane, q)
    forces = space.forces(np.zeros_like(space.x))
    flows = circuit.flows(np.zeros_like(space.x), forces)
    expected = (forces + 2e5 * circuit.rod_side_areas) / circuit.piston_areas
    np.testing.assert_allclose(flows.load, np.maximum(expected, 2e5), rtol=1e-12)
    np.testing.assert_array_equal(flows.flow, 0.0)


def test_power_balance_along_the_paper_segments(crane, motions):
    """Σ F_i ẋ_i = d/dt (T + V), payload included, along every baseline motion: the actuator
    forces F_H = M_H ẍ + N_H do the work the crane stores. ẍ and the energy's rate are both
    central differences on the 3 ms grid, so they agree to O(h²): within 1e-5 of the peak power
    (3e-6 measured)."""
    assert crane.payload == 100.0
    for runs in motions.values():
        for motion in runs:
            t, q = motion.t[0], motion.q[0]
            v = motion.states.v.reshape(q.shape)
            power = np.einsum("ti,ti->t", motion.forces[0], motion.x_dot[0])
            stored = np.gradient(mechanical_energy(crane, q, v), t, edge_order=2)
            inside = slice(2, -2)
            error = np.abs(power[inside] - stored[inside]).max()
            assert error <= 1e-5 * np.abs(power).max(), error


def test_energy_chain(crane, motions):
    """LS pump energy ≥ the useful hydraulic work ∫ Σ p_L Q dt ≥ the mechanical work
    ∫ Σ F ẋ dt = Δ(T + V); CP ≥ LS where loads stay below p_S − Δp_LS."""
    circuit = crane.circuit()
    for runs in motions.values():
        for motion in runs:
            t = motion.t[0]
            ls = motion.energy(circuit.load_sensing)[0]
            cp = motion.energy(circuit.constant_pressure)[0]
            useful = np.trapezoid(motion.flows.useful_power[0], t)
            mechanical = np.trapezoid(np.einsum("ti,ti->t", motion.forces[0], motion.x_dot[0]), t)
            v = motion.states.v.reshape(motion.q.shape)[0]
            stored = mechanical_energy(crane, motion.q[0], v)
            assert mechanical == pytest.approx(stored[-1] - stored[0], abs=1e-3 * ls)
            assert ls >= useful >= mechanical
            assert motion.flows.load[0].max() < 180e5 - 20e5
            assert cp >= ls


def test_flow_law_is_the_weighted_pseudoinverse(crane):
    """MinFlow's ẋ tracks the task and has the least Σ (A_A ẋ)² among the task's solutions."""
    q = random_configurations(crane, 4, seed=43, margin=0.1)
    space = actuator_space(crane, q)
    y_dot = np.random.default_rng(44).normal(size=(4, crane.m))
    x_dot = MinFlow().resolve(space, y_dot)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", space.J_H, x_dot), y_dot, atol=1e-12)
    areas = crane.circuit().piston_areas
    for i in range(4):
        null = np.linalg.svd(space.J_H[i])[2][-1]  # the task's one self-motion direction
        along = [np.sum((areas * (x_dot[i] + e * null)) ** 2) for e in (-1e-3, 0.0, 1e-3)]
        assert along[1] < along[0] and along[1] < along[2]
        weighted = areas**2 * x_dot[i] @ null
        assert abs(weighted) <= 1e-12 * np.linalg.norm(areas**2 * x_dot[i])


def test_hydraulic_objectives_run_through_the_searches(crane, cycle):
    """Peak pump flow through the fast search and the sweep, and the pump energies (integral,
    dynamic) through the fast search: the best start is feasible and no sampled start beats it.
    """
    segment = cycle["2-3"]
    fast = improved_start(crane, segment, FLOW)
    sweep = improved_start(crane, segment, FLOW, samples=25, method="sweep")
    assert fast.best is not None and sweep.best is not None
    assert fast.best.peak <= sweep.best.peak * 1.005
    motion = fast.motion()
    peak = motion.flows.pump_flow[0].max() / LITRES_PER_MINUTE
    assert peak == pytest.approx(fast.best.peak, rel=2e-3)
    for objective, supply in ((LS_ENERGY, "load_sensing"), (CP_ENERGY, "constant_pressure")):
        search = improved_start(crane, segment, objective, samples=15, method="sweep")
        assert search.best is not None
        energies = [s.peak for s in search.feasible]
        assert search.best.peak == min(energies)
        best = search.motion()
        kilojoules = best.energy(getattr(crane.circuit(), supply))[0] / 1e3
        assert kilojoules == pytest.approx(search.best.peak, rel=5e-3)


def test_a_pump_energy_study_runs_its_cycle_section_and_names_energies_as_energies(tmp_path):
    """`study --objective ls_energy` with its cycle section, which runs in a second process:
    the objective (a measure of a module function's partial) is sent back from it, where its
    measure used to be a closure that could not be pickled (an internal error). Its value is
    the integral of the pump power, in kJ: the tables, report.json and the figures' names say
    so (they said "peak LS pump power (kW)"), and the per-segment plan's value over the cycle is
    the sum of its segments' energies, not the largest."""
    out = tmp_path / "out"
    run = run_cli(
        "study", "--objective", "ls_energy", "--samples", "10", "--cycles", "1", "--out", str(out)
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "report.json").read_text())
    assert (report["studies"][0]["measure"], report["studies"][0]["unit"]) == (
        "∫ LS pump power dt",
        "kJ",
    )
    cycle = report["cycle"]
    assert (cycle["measure"], cycle["unit"]) == ("∫ LS pump power dt", "kJ")
    energies = [s["best"]["peak"] for s in cycle["per_segment"]["segments"]]
    plan = re.search(r"per-segment plan: .*, ∫ LS pump power dt ([0-9.]+) kJ", run.stdout)
    assert plan and float(plan.group(1)) == pytest.approx(sum(energies), rel=1e-4)
    assert "peak LS" not in run.stdout and " kW" not in run.stdout
    assert (out / "figa_peak_ls_energy.png").exists()


def test_objectives_pickle_and_name_their_values():
    """Every built-in objective survives pickling with the same measure; a peak is named as
    one in the measure's unit, an integral of a power as an energy."""
    space = actuator_space(load_robot("hiab031"), np.array([[0.3, -0.8, 0.5]]))
    x_dot = np.array([[0.02, -0.03, 0.1]])
    for objective in (VELOCITY, ENERGY, FLOW, LS_ENERGY, CP_ENERGY):
        again = pickle.loads(pickle.dumps(objective))
        if not objective.dynamic:
            assert again.measure(space, x_dot) == objective.measure(space, x_dot)
    units = {
        o.name: (o.value_label, o.value_unit(space.robot.actuators)) for o in (VELOCITY, LS_ENERGY)
    }
    assert units == {"velocity": ("peak ẋᵀẋ", "m²/s²"), "ls_energy": ("∫ LS pump power dt", "kJ")}
    assert LS_ENERGY.value_axis(space.robot.actuators) == "∫ LS pump power dt (kJ)"


def test_limits_of_the_circuit_are_named(crane, motions):
    """The M_H-weighted law drives the light telescope faster than its 0.25 m/s on segment 1-2:
    the violation names the cylinder, the limit and the amount in m/s."""
    weighted = motions["1-2"][1]
    violations = weighted.hydraulic_violations(0)
    assert violations and violations[0].actuator == "x3 speed"
    assert str(violations[0]).startswith("x3 speed ")
    assert "m/s past its upper limit" in str(violations[0])
    assert np.abs(weighted.x_dot[0, :, 2]).max() > 0.25
    assert not motions["1-2"][0].hydraulic_violations(0)


def test_splines_between_solved_strokes_match_exact_configurations(crane, cycle):
    """The energy bound's tables interpolate x between solved held strokes: against Newton's
    solution at the midpoints, the error is below 5e-5 m (largest at the stroke's ends) and
    mostly below 1e-6 m."""
    segment = cycle["3-1"]
    t = np.linspace(0.0, segment.duration, 6)
    tables = Tables(crane, segment, [2], Limits.strokes(crane), t)
    middles = (tables.axes[0][1:] + tables.axes[0][:-1]) / 2
    q, found = _nodes(crane, segment, [2], middles[:, None], t)
    x, _, _, usable = tables.at(np.tile(middles[:, None], (len(t), 1, 1)))
    exact = actuator_space(crane, q.reshape(-1, crane.n)).x.reshape(x.shape)
    both = found & usable
    assert both.sum() > EXACT
    error = np.abs(x - exact)[both]
    assert error.max() < 5e-5 and np.median(error) < 1e-6


@pytest.fixture(scope="module")
def reach():
    """r = 2 on a circuit: the crane's tool reach alone (world x, m = 1) from 3.5 to 2 m at
    0.5 m/s, the fold cylinder x2 and the telescope x3 held."""
    robot = load_robot("hiab031", task_axes="x")
    return robot, Segment("in", np.array([3.5]), np.array([2.0]), 0.5), ("x2", "x3")


@pytest.fixture(scope="module")
def reach_cells(reach):
    """The reach's two-held tables at the centres of their cells: the tables, the centres'
    held values (N + 1, G, 2) and the cells' step (2,), the tables' x, q and where usable, and
    Newton's solution from the interpolated q, with where it was found."""
    robot, segment, held = reach
    rows = robot.actuators.rows(held)
    t = np.linspace(0.0, segment.duration, 4)
    tables = Tables(robot, segment, rows, Limits.strokes(robot), t)
    steps = np.array([axis[1] - axis[0] for axis in tables.axes])
    middles = [(axis[1:] + axis[:-1]) / 2 for axis in tables.axes]
    centres = np.stack(np.meshgrid(*middles, indexing="ij"), -1).reshape(-1, 2)
    values = np.tile(centres, (len(t), 1, 1))
    x, _, q, usable = tables.at(values)
    exact, found = tables.solved(values, q)
    return tables, values, steps, x, q, usable, exact, found


def test_bilinear_tables_between_solved_strokes_match_exact_configurations(reach_cells):
    """With two held cylinders the tables interpolate x bilinearly between solved strokes.
    Against Newton's solution at the cells' centres from the interpolated configuration, the
    error is below 1 cm (7 mm measured) in the cells whose four corners lie on one branch
    (their configurations within 0.2 of each other, rad or m)."""
    tables, values, steps, x, _, usable, exact, found = reach_cells
    corners = np.stack(
        [
            tables.at(values + np.array(d) * steps / 2)[2]
            for d in itertools.product((-1, 1), (-1, 1))
        ]
    )
    one = found & usable & (np.abs(corners.max(0) - corners.min(0)).max(-1) < 0.2)
    assert one.sum() > 0.5 * (found & usable).sum()
    error = np.abs(x - exact.x.reshape(x.shape))[one]
    assert error.max() < 1e-2


def test_two_held_tables_use_no_cell_between_the_tasks_two_branches(reach_cells):
    """The reach alone has two solutions inside the joint ranges, the lift up or down, and the
    seeds pick either: a cell with corners on both would interpolate across them, x wrong by
    up to 26 cm (41 % of the usable cells). No usable cell does: at every one's centre Newton's
    method finds the task from the interpolated configuration, and the tables' x lies within
    1 cm of it (9 mm measured)."""
    _, _, _, x, _, usable, exact, found = reach_cells
    assert usable.sum() > 500 and found[usable].all()
    assert np.abs(x - exact.x.reshape(x.shape))[usable].max() < 1e-2


def test_two_held_cylinders_get_an_energy_bound_within_the_circuit(reach):
    """The energy bound over both held cylinders' histories keeps their strokes and, on every
    transition, the circuit's limits (load pressures, pump flow, cylinder speeds) with the
    flows the bound prices; its energy is the LS pump energy of those transitions. Its tables
    leave out the cells across the reach's fold, so a motion that crosses it (the improved
    start's, 3376 J, below the optimum's 4460 J) is not searched: the optimum converges yet is
    withheld as no bound, and says why."""
    robot, segment, held = reach
    bound = energy_optimum(robot, segment, None, held, grids=(10, 20))
    assert bound.held == held and bound.r.shape == (21, 2)
    assert np.abs(bound.r - bound.x[:, robot.actuators.rows(held)]).max() < 1e-9
    strokes = robot.actuators
    assert np.all((bound.x >= strokes.lower - 1e-9) & (bound.x <= strokes.upper + 1e-9))
    assert _circuit_margin(robot, bound).min() >= -TOLERANCE
    assert bound.change < CONVERGED and bound.folded > 0 and not bound.converged
    assert bound.failure.startswith("no bound: the tables left out ")
    assert "across the task's fold" in bound.failure


def test_the_integral_optimum_keeps_the_circuit_s_limits_when_given_a_supply(cycle):
    """The least ∫ ẋᵀẋ dt along segment 1-2 moves the fold cylinder at 0.135 m/s; on a circuit
    that limits it to 0.12 m/s (tests/data/slow_fold.toml) the optimum given the circuit's
    supply keeps that limit and the load pressures and pump flow on every transition."""
    robot = load_robot("hiab031", hydraulics=Path(__file__).parent / "data" / "slow_fold.toml")
    travel = dataclasses.replace(VELOCITY, name="travel", reduction="integral")
    circuit, segment = robot.circuit(), cycle["1-2"]
    free = integral_optimum(robot, segment, travel, "x3", grids=(10,))
    kept = integral_optimum(robot, segment, travel, "x3", grids=(10,), supply=circuit.supply)
    assert _circuit_margin(robot, free).min() < 0 < _circuit_margin(robot, kept).min()
    assert kept.optimum > free.optimum


def _circuit_margin(robot, found):
    """How far inside the circuit's limits each transition of ``found`` keeps, with the forces
    at rest at its nodes (N, 2c + 1)."""
    circuit, h = robot.circuit(), found.t[1]
    forces = actuator_space(robot, found.q).N_H
    x_dot = np.diff(found.x, axis=0) / h
    flows = circuit.flows(x_dot, (forces[1:] + forces[:-1]) / 2)
    return Limits.hydraulic(robot).margin(hydraulic_values(circuit, x_dot, flows))


@pytest.fixture(scope="module")
def bounds(crane, cycle):
    return {s.name: energy_optimum(crane, s, None, "x3") for s in cycle.segments}


def test_energy_bound_converges_and_is_below_every_strategy(crane, cycle, motions, bounds):
    """On every paper segment the LS energy bound changes by less than 0.5 % on refinement,
    keeps every limit (a speed limit binds it), and lies below every baseline and the improved
    start's energy; the improved start lands between the bound and the default start."""
    supply = crane.circuit().load_sensing
    for segment in cycle.segments:
        bound = bounds[segment.name]
        assert bound.converged, bound.grids
        improved = improved_start(crane, segment, VELOCITY).motion()
        energies = [m.energy(supply)[0] for m in motions[segment.name]]
        assert all(bound.energy < e for e in [*energies, improved.energy(supply)[0]])
        assert improved.energy(supply)[0] < energies[0]
        stroke = crane.actuators["x3"]
        assert np.all((bound.r >= stroke.lower) & (bound.r <= stroke.upper))
        speeds = np.abs(np.diff(bound.r) / np.diff(bound.t))
        assert speeds.max() <= 0.25 + 1e-9


def test_inertia_changes_the_energy_by_little(crane, motions):
    """The bound leaves inertia and velocity terms out of the forces: along the baselines they
    change the LS pump energy by under 1 %."""
    circuit = crane.circuit()
    for runs in motions.values():
        for motion in runs:
            k, T, n = motion.q.shape
            q = motion.q.reshape(k * T, n)
            static = actuator_space(crane, q).forces(np.zeros((k * T, n))).reshape(k, T, n)
            full = motion.energy(circuit.load_sensing)[0]
            power = circuit.flows(motion.x_dot, static).power(circuit.load_sensing)
            quasi_static = np.trapezoid(power[0], motion.t[0])
            assert abs(quasi_static - full) < 0.01 * full


def test_hydraulics_file_errors_name_the_value_and_the_choices(tmp_path):
    names, rotary = ["x1", "x2", "x3"], [False, False, False]
    good = {
        "supply": "LS",
        "ls_margin": 20,
        "cp_pressure": 180,
        "relief": 210,
        "pump_flow": 100,
        "tank": 2,
        "cylinders": {"x1": {"bore": 80, "rod": 45, "max_speed": 0.25, "max_acceleration": 1}},
    }
    assert circuit_from_table(good, "f.toml", names, rotary).names == ("x1",)
    cases = [
        ({"supply": "XX"}, '[hydraulics] supply = "XX" must be one of "LS", "CP"'),
        ({"relief": "high"}, 'relief = "high" must be a finite number (relief pressure, bar)'),
        (
            {"cylinders": {"x9": good["cylinders"]["x1"]}},
            "no actuator 'x9'; actuators: ['x1', 'x2', 'x3']",
        ),
        (
            {"cylinders": {"x1": {"bore": 40, "rod": 45, "max_speed": 1, "max_acceleration": 1}}},
            "0 ≤ rod < bore",
        ),
        (
            {"cylinders": {"x1": {"bore": 80, "rod": 45, "max_speed": 1}}},
            "f.toml: [hydraulics.cylinders.x1]: missing key 'max_acceleration'",
        ),
        ({"cp_pressure": 300}, "needs tank < cp_pressure ≤ relief"),
        ({"colour": 1}, "unknown keys ['colour']"),
    ]
    for change, message in cases:
        with pytest.raises(InvalidInputError, match=re.escape(message)):
            circuit_from_table({**good, **change}, "f.toml", names, rotary)
    dotted = {"bore": 80, "rod": 45, "max_speed": 1}  # a name TOML writes quoted
    with pytest.raises(
        InvalidInputError, match=re.escape('f.toml: [hydraulics.cylinders."lift-cyl.1"]: missing')
    ):
        circuit_from_table(
            {**good, "cylinders": {"lift-cyl.1": dotted}}, "f.toml", ["lift-cyl.1"], [False]
        )
    path = tmp_path / "h.toml"
    path.write_text("[hydraulics]\nsupply = 'CP'\n")
    with pytest.raises(
        InvalidInputError, match=r"h.toml: \[hydraulics\]: missing keys \['ls_margin', "
    ):
        load_robot("hiab031", hydraulics=path)
    run = run_cli("describe", "--hydraulics", str(tmp_path / "none.toml"))
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert "cannot read hydraulics file" in run.stderr and len(run.stderr.splitlines()) == 1


def test_a_robot_without_hydraulics_says_how_to_declare_them():
    with pytest.warns(UserWarning, match="driven directly"):
        panda = load_robot("panda")
    with pytest.raises(InvalidInputError, match=r"declare a \[hydraulics\] table"):
        panda.circuit()


def test_shortest_duration_reaches_a_limit_and_exceeds_none(crane, cycle):
    """TOPP-RA's timing of each improved path, checked on the re-timed motion: some limit is
    used to within 0.1 % and none is passed; the path is the same, only faster than 0.5 m/s."""
    for segment in cycle.segments:
        motion = improved_start(crane, segment, VELOCITY).motion()
        retimed = shortest_duration(motion)
        usage = retimed.usage(crane)
        assert max(usage.values()) == pytest.approx(1.0, abs=1e-3), usage
        assert all(share <= 1.0 + 1e-12 for share in usage.values()), usage
        assert retimed.duration < segment.duration
        columns = crane.circuit().columns
        np.testing.assert_allclose(retimed.x[[0, -1]], motion.x[0, [0, -1]][:, columns], atol=1e-9)
        np.testing.assert_allclose(retimed.x_dot[[0, -1]], 0.0, atol=1e-9)
        rate = np.gradient(retimed.x, retimed.t, axis=0)
        assert np.abs(rate - retimed.x_dot).max() < 1e-2 * crane.circuit().max_speeds.max()


BEND = np.array([[3.5, -0.5], [1.0, -0.5], [2.25, 3.0]])  # the paper's points 1, 2, 3
BEND_SPEED = 0.3  # m/s: the corner at 2.5 m / 0.3 m/s = 8.33 s, between the 10 ms grid's samples


def _phase_plane(crane, piece: Segment, start: np.ndarray, time_step: float):
    """The fastest duration from rest to rest of the strokes' path of the pseudoinverse along
    ``piece`` from ``start``, and that motion, by the phase plane: on the motion's samples
    (``time_step`` apart), s = t / T uniform (spacing h), with x' = T ẋ and x'' = T² ẍ, the
    speed limit curve u_max(s) = ṡ_max² = min(min_i (v_i / |x'_i|)², (Q_max / Σ A_i |x'_i|)²)
    (A_i the piston area where x_i extends, the annulus where it retracts) and the
    accelerations −a_i ≤ x'_i s̈ + x''_i u ≤ a_i, which bound s̈ = u'/2 to [α(s, u), β(s, u)].
    Forward from u(0) = 0, u_{j+1} = min(u_max, u_j + 2h β(s_j, u_j)); backward from
    u(1) = 0, u_j = min(forward u_j, u_{j+1} − 2h α(s_{j+1}, u_{j+1})); then, s̈ constant on
    each interval, T_min = Σ 2h / (√u_j + √u_{j+1})."""
    motion = simulate(crane, VELOCITY.resolver, piece, start, time_step, tolerance=1e-10)
    circuit = crane.circuit()
    T = motion.t[0, -1]
    first = motion.x_dot[0][:, circuit.columns] * T
    second = motion.x_ddot[0][:, circuit.columns] * T**2
    area = np.where(first > 0, circuit.piston_areas, circuit.rod_side_areas)
    with np.errstate(divide="ignore"):
        speed = np.min((circuit.max_speeds / np.abs(first)) ** 2, axis=1)
        flow = (circuit.pump_flow / (area * np.abs(first)).sum(axis=1)) ** 2
    u_max, h = np.minimum(speed, flow), 1.0 / (len(first) - 1)

    def bounds(j, u):
        """[α, β]: each cylinder's (±a_i − x''_i u) / x'_i, the lower and upper ends ordered."""
        ends = (np.outer([-1.0, 1.0], circuit.max_accelerations) - second[j] * u) / first[j]
        return np.max(ends.min(axis=0)), np.min(ends.max(axis=0))

    forward = np.zeros(len(first))
    for j in range(len(first) - 1):
        forward[j + 1] = min(u_max[j + 1], max(0.0, forward[j] + 2 * h * bounds(j, forward[j])[1]))
    u = np.zeros(len(first))
    for j in range(len(first) - 1, 0, -1):
        u[j - 1] = min(forward[j - 1], max(0.0, u[j] - 2 * h * bounds(j, u[j])[0]))
    root = np.sqrt(u)
    return float(np.sum(2 * h / (root[1:] + root[:-1]))), motion


def test_shortest_duration_stops_at_a_polyline_s_corner_as_the_phase_plane_does(crane):
    """A two-piece polyline turns at its corner: ẋ = x' ṡ would jump there at any ṡ > 0, so
    its fastest timing stops there, and is the sum of each straight piece's fastest timing
    from rest to rest. Against that, by the phase plane on each piece simulated as its own
    line (the second from the first one's end), converged: halving its step moves it by less
    than 1e-4 of itself (it is first order in the step, and moves by 4e-5). TOPP-RA's timing
    is first order in its own grid (two intervals per sample, the limits held only at its grid
    points, the timing then stretched by the least k that keeps them between): 0.18 % slower
    at 400 samples, 0.12 % at 800, so 0.5 % bounds it at 400 with room to spare, and 800
    must come closer. A spline through the corner (what was timed before) came out 7 % slower
    at 400 samples, and slower still with more. The re-timed motion passes no limit, reaches
    one, and rests at the corner, where both pieces meet at the motion's stroke there."""
    segment = Segment.along("bend", Polyline(BEND), BEND_SPEED)
    start = default_start(crane, segment, ["x3"])[1][None]
    motion = simulate(crane, VELOCITY.resolver, segment, start, tolerance=1e-10)
    np.testing.assert_allclose(corners(segment), [2.5 / BEND_SPEED], rtol=1e-12)
    legs = [Segment.along(f"leg{i}", Line(*BEND[i : i + 2]), BEND_SPEED) for i in range(2)]
    references = []
    for time_step in (0.004, 0.002):
        total, at = 0.0, start
        for leg in legs:
            duration, run = _phase_plane(crane, leg, at, time_step)
            total, at = total + duration, run.q[0, -1][None]
        references.append(total)
    reached = run.x[0, 0]  # the corner's strokes, where the second line starts
    reference = references[-1]
    assert abs(references[0] - reference) < 1e-4 * reference, references
    coarse, fine = (shortest_duration(motion, samples=n) for n in (400, 800))
    lowest = (1 - 1e-4) * reference  # the reference's own error aside
    assert lowest <= coarse.duration <= 1.005 * reference, (coarse.duration, reference)
    assert lowest <= fine.duration < coarse.duration, (fine.duration, reference)

    usage = coarse.usage(crane)
    assert max(usage.values()) == pytest.approx(1.0, abs=1e-3), usage
    assert all(share <= 1.0 + 1e-12 for share in usage.values()), usage
    columns = crane.circuit().columns
    (resting,) = np.flatnonzero(np.diff(coarse.t) == 0)  # the corner, once per piece
    np.testing.assert_allclose(coarse.x_dot[[0, resting, resting + 1, -1]], 0.0, atol=1e-9)
    np.testing.assert_allclose(coarse.x[resting], coarse.x[resting + 1], rtol=0, atol=1e-12)
    # the corner's strokes, read from the samples 10 ms apart by second-order Taylor steps,
    # each off by |x‴| δ³ / 6 with δ < 10 ms: 1e-8 m allows |x‴| up to 60 m/s³
    np.testing.assert_allclose(coarse.x[resting], reached[columns], rtol=0, atol=1e-8)
    for piece in (slice(0, resting + 1), slice(resting + 1, None)):
        rate = np.gradient(coarse.x[piece], coarse.t[piece], axis=0)
        assert np.abs(rate - coarse.x_dot[piece]).max() < 1e-2 * crane.circuit().max_speeds.max()


def test_shortest_duration_goes_on_where_the_path_does_not_turn(crane):
    """A trapezoidal profile's ramp ends and a polyline's point on the line through its
    neighbours are breaks where ẋ is continuous: no corner, and the line with such a point
    times as the line without it."""
    points = np.array([BEND[0], (BEND[0] + BEND[1]) / 2, BEND[1]])
    plain, split = (
        Segment.along(name, shape, 0.5, "trapezoidal", 0.5)
        for name, shape in (("plain", Line(*points[[0, 2]])), ("split", Polyline(points)))
    )
    assert len(split.breaks) == 3 and len(plain.breaks) == 2
    start = default_start(crane, plain, ["x3"])[1][None]
    durations = []
    for segment in (plain, split):
        assert corners(segment).size == 0
        motion = simulate(crane, VELOCITY.resolver, segment, start, tolerance=1e-10)
        durations.append(shortest_duration(motion).duration)
    assert durations[1] == pytest.approx(durations[0], rel=1e-6)


def test_a_slew_alone_has_no_shortest_duration(crane, tmp_path):
    """The slewing crane with the planar crane's circuit, its slew driven directly, following a
    quarter circle about its column at one radius and height: the slew alone moves the tool,
    every cylinder stands still, and no limit of the circuit bounds the path's speed. TOPP-RA
    timed it in 0.2 ms (a tool at 17 km/s); it has no shortest duration, and says why. A
    chord, where they stand still for an instant only, has one."""
    folder = crane.urdf.parent.parent / "hiab031_slewing"
    text = (crane.urdf.parent / "robot.toml").read_text()
    (tmp_path / "circuit.toml").write_text(text[text.index("[hydraulics]") :])
    slewing = load_robot(folder / "robot.toml", hydraulics=tmp_path / "circuit.toml")
    assert "slew" not in [slewing.actuators.names[c] for c in slewing.circuit().columns]
    radius, height = 2.2, 1.8
    corner = np.array([radius, radius, 0.0]) / np.sqrt(2) + [0, 0, height]
    arc = Arc.through(np.array([radius, 0, height]), corner, np.array([0, radius, height]))
    quarter = Segment.along("swing", arc, 0.5)
    start = default_start(slewing, quarter, ["x3"])[1][None]
    motion = simulate(slewing, VELOCITY.resolver, quarter, start)
    cylinders = motion.x[0][:, slewing.circuit().columns]
    assert np.ptp(cylinders, axis=0).max() < 1e-9 and np.ptp(motion.x[0, :, 0]) > 1.5
    with pytest.raises(RedundancyError, match=r"^unbounded: slew alone moves the tool from"):
        shortest_duration(motion)
    figures = peers.hydraulics(motion)
    assert figures["shortest_duration_s"] is None
    assert "circuit limits only cylinders" in figures["shortest_duration_reason"]
    # the task's chord from lift to swing at 0.15 m/s: the cylinders turn back together at its
    # middle and stand still there for one sample, which is no stretch: its speed is bounded
    chord = WorkCycle.from_toml(slewing.task_file, dimension=slewing.m)["lift-swing"]
    slow = Segment.along("slow", chord.shape, 0.15)
    motion = simulate(slewing, VELOCITY.resolver, slow, default_start(slewing, slow)[1][None])
    steps = np.abs(np.diff(motion.x[0][:, slewing.circuit().columns], axis=0)).max(axis=1)
    assert steps.min() < 1e-9 and steps.max() > 1e-4  # still for an instant, moving elsewhere
    assert 1.0 < shortest_duration(motion).duration < slow.duration


def test_circuit_limits_count_in_the_searches(crane, cycle, tmp_path):
    """With the circuit's limits counted, a pump of 70 L/min cuts the feasible starts of 1-2 and
    3-1 where the pump flow passes it; the fast search and the sweep agree on the new ends within
    one sample spacing and on the best peak within 0.5 %. The M_H-weighted law, whose telescope
    passes its 0.25 m/s everywhere on 1-2, keeps no start there."""
    text = (crane.urdf.parent / "robot.toml").read_text()
    table = text[text.index("[hydraulics]") :].replace("pump_flow = 100.0", "pump_flow = 70.0")
    (tmp_path / "pump.toml").write_text(table)
    small = load_robot("hiab031", hydraulics=tmp_path / "pump.toml")
    spacing = (crane.actuators["x3"].upper - crane.actuators["x3"].lower) / 99
    for name, cut in (("1-2", 0.9), ("3-1", 0.6)):
        segment = cycle[name]
        free = improved_start(small, segment, VELOCITY)
        fast = improved_start(small, segment, VELOCITY, circuit=True)
        sweep = improved_start(small, segment, VELOCITY, method="sweep", circuit=True)
        assert free.feasible_range[0] < cut < fast.feasible_range[0]
        assert abs(fast.feasible_range[0] - sweep.feasible_range[0]) < spacing
        assert fast.best.peak <= sweep.best.peak * 1.005
        pumped = fast.motion().flows.pump_flow[0].max()
        assert pumped <= small.circuit().pump_flow * (1 + 1e-9)
        low = [s for s in fast.samples if s.peak is not None and s.values[0] < cut]
        assert any("pump flow" in (s.reason or "") for s in low)
    energy = improved_start(crane, cycle["1-2"], ENERGY, circuit=True)
    assert energy.best is None
    assert str(energy.closest_violation).startswith("x3 speed")


def test_cylinders_declared_in_the_transmissions_equal_the_toml_tables(crane, tmp_path):
    """The crane's cylinders given as <cylinder> elements of its transmissions, with the
    machine's supply alone in robot.toml, make the same circuit as the bundled tables; a
    cylinder declared in both places, or with an unknown attribute, is one line."""
    folder = crane.urdf.parent
    urdf = crane.urdf.read_text()
    for name, (bore, rod) in {"x1": (80, 45), "x2": (70, 40), "x3": (50, 32)}.items():
        head = f'<actuator name="{name}">'
        cylinder = f'<cylinder bore="{bore}" rod="{rod}" max_speed="0.25" max_acceleration="1"/>'
        assert urdf.count(head) == 1
        urdf = urdf.replace(head, head + cylinder)
    (tmp_path / "crane.urdf").write_text(urdf)
    toml = (folder / "robot.toml").read_text()
    machine = toml[: toml.index("[hydraulics.cylinders.x1]")]
    (tmp_path / "robot.toml").write_text(machine.replace("hiab031.urdf", "crane.urdf"))
    declared, bundled = load_robot(tmp_path / "robot.toml").circuit(), crane.circuit()
    for field in ("names", "cylinders", "supply", "constant_pressure", "relief", "pump_flow"):
        assert getattr(declared, field) == getattr(bundled, field)
    np.testing.assert_array_equal(declared.columns, bundled.columns)
    (tmp_path / "both.toml").write_text(toml.replace("hiab031.urdf", "crane.urdf"))
    with pytest.raises(InvalidInputError, match=r"cylinders \['x1', 'x2', 'x3'\] are declared"):
        load_robot(tmp_path / "both.toml")
    (tmp_path / "crane.urdf").write_text(urdf.replace('rod="45"', 'rod="45" colour="red"'))
    with pytest.raises(RobotDescriptionError, match=r"unknown attributes \['colour'\]"):
        load_robot(tmp_path / "robot.toml")


def test_telescope_at_constant_speed_by_hand(crane):
    """The booms still and the telescope moving at a constant ±0.1 m/s: ẍ = 0, and the only
    force on x3 is the weight of telescope and payload along boom 2, (36 + 100) kg · 9.81 m/s² ·
    sin(θ1 + θ2) with θ_i = q_i + c_i (Eqs. 2-3); here boom 2 points 47.67° down, so it is
    −986.3 N (the cylinder holds the telescope in). Extending, the load overruns; retracting,
    p_L = (986.3 N + p_T A_A) / A_B = 11.90 bar."""
    q = np.array([np.radians(100), np.radians(60), 0.7])
    c1, c2 = np.radians(-57.70), np.radians(-149.97)
    weight = 136 * 9.81 * np.sin(q[0] + c1 + q[1] + c2)
    assert weight == pytest.approx(-986.316, abs=1e-3)
    a, b = math.pi * 0.05**2 / 4, math.pi * (0.05**2 - 0.032**2) / 4
    circuit = crane.circuit()
    for speed in (0.1, -0.1):
        space = actuator_space(crane, q, [0.0, 0.0, speed])
        np.testing.assert_allclose(space.A_dot[0] @ [0.0, 0.0, speed], 0.0, atol=1e-15)
        force = space.forces(np.zeros((1, 3)))
        assert force[0, 2] == pytest.approx(weight, rel=1e-9)
        flows = circuit.flows(space.x_dot, force)
        if speed > 0:
            assert flows.flow[0, 2] == pytest.approx(a * 0.1, rel=1e-12)
            assert (weight + 2e5 * b) / a < 2e5 and flows.overrunning[0, 2]
        else:
            assert flows.flow[0, 2] == pytest.approx(b * 0.1, rel=1e-12)
            assert flows.load[0, 2] == pytest.approx((-weight + 2e5 * a) / b, rel=1e-9)
            assert flows.load[0, 2] / BAR == pytest.approx(11.90, abs=5e-3)
        assert flows.pump_flow[0] * 60000 == pytest.approx(flows.flow[0, 2] * 60000, rel=1e-12)


def test_the_study_goes_on_where_a_bound_fails(crane, cycle, monkeypatch):
    """A bound whose solver fails (as the min-max bound of peak pump flow does on 3-1, where
    SLSQP steps out of the task's reach) leaves that segment without a bound, says why in one
    line, and the study goes on."""
    import redundancy.study.study as study_module

    solved = study_module.global_optimum

    def failing_on_2_3(robot, segment, *args, **kwargs):
        if segment.name == "2-3":
            raise UnreachableError("no configuration reaches the task at t = 1.000 s")
        return solved(robot, segment, *args, **kwargs)

    monkeypatch.setattr(study_module, "global_optimum", failing_on_2_3)
    study = run_study(crane, cycle, (VELOCITY,), samples=5, progress=False, cycles=0)
    segments = json.loads(json.dumps(study.report(), allow_nan=False))["studies"][0]["segments"]
    assert [s["bound"] is None for s in segments] == [False, True, False]
    assert segments[1]["bound_failure"] == "no configuration reaches the task at t = 1.000 s"
    assert "no bound: no configuration reaches the task" in study_table(study)


def test_each_supply_bounds_the_load_pressures_it_can_serve(crane):
    """Under LS a load may reach relief − Δp_LS = 190 bar; under CP only p_S = 180 bar; the
    energy bound of each supply keeps its own."""
    circuit = crane.circuit()
    for supply, most in ((circuit.load_sensing, 190e5), (circuit.constant_pressure, 180e5)):
        limits = Limits.hydraulic(crane, supply)
        np.testing.assert_allclose(limits.upper[:3], most)


def test_a_segment_shorter_than_a_time_step_gets_every_figure(crane, monkeypatch):
    """A 0.1 mm move (0.2 ms) is sampled on `MIN_INTERVALS` intervals: ẍ, the forces, the flows
    and the fastest timing of its path are all defined. Where TOPP-RA finds no timing, the
    figure is None and the table shows '-'."""
    short = Segment("short", np.array([3.5, -0.5]), np.array([3.5, -0.4999]), 0.5)
    for name, resolver in BASELINES:
        run = fixed_start_run(crane, resolver, name, short)
        assert run.trajectory.t.shape == (1, MIN_INTERVALS + 1)
        assert run.trajectory.max_tracking_error[0] < 1e-12
        figures = run.summary()["hydraulics"]
        assert 0 < figures["shortest_duration_s"] < 1.0 and np.isfinite(figures["ls_energy_kj"])
    monkeypatch.setattr(peers, "shortest_duration", _no_timing)
    untimed = fixed_start_run(crane, BASELINES[0][1], BASELINES[0][0], short)
    assert untimed.summary()["hydraulics"]["shortest_duration_s"] is None
    cycle = WorkCycle("short", (short,))
    study = run_study(crane, cycle, (VELOCITY,), 3, bound=False, progress=False, cycles=0)
    study = dataclasses.replace(study, runs=(untimed,))
    last = hydraulic_table(study).splitlines()[-1]
    assert last.endswith("-  t_min: TOPP-RA found no timing; kept")


def _no_timing(motion):
    raise RedundancyError("TOPP-RA found no timing")
