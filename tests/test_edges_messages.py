"""Machines at their edges, as a new user meets them: every message names the file and the table
that fix it, `check` reports what a study would refuse, quantities show in their own units, and a
kinematic-only robot's default study runs what needs no masses."""

import re
import warnings
from pathlib import Path

import meshcat
import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from scipy.spatial import Delaunay

from redundancy import (
    ENERGY,
    VELOCITY,
    GradientProjection,
    actuator_space,
    load_robot,
    run_study,
)
from redundancy.cli import _load_task, _play_motion, main, parser
from redundancy.model.hydraulics import BAR
from redundancy.model.loading import bundled_root
from redundancy.planning.integrate import simulate
from redundancy.planning.tasks import WorkCycle
from redundancy.resolution.limits import amount
from redundancy.study.check import span
from redundancy.viz.playback import Playback, Recording
from redundancy.viz.report import _hydraulics
from redundancy.viz.tables import hydraulic_table

FIXTURES = Path(__file__).parent / "fixtures" / "intake"
PLANAR = Path(__file__).parent / "data" / "planar4r"
TASK = """name = "arm test cycle"
speed = 0.5
segments = ["1-2"]
held = {held}
[points]
1 = {one}
2 = {two}
"""


def run(argv, capsys):
    """``redundancy ARGV`` in this process: the exit status, stdout, and stderr's lines."""
    with warnings.catch_warnings():
        try:
            status = main(argv)
        except SystemExit as exit:
            status = exit.code
    captured = capsys.readouterr()
    return status, captured.out, captured.err.strip().splitlines()


def errors(lines):
    return [line for line in lines if not line.startswith("redundancy: note:")]


def arm(tmp_path, held='["stick_joint"]', axes="xz", one="[2.8, -0.2]", two="[2.8, 1.2]"):
    """The continuous-joint test arm, its stick joint left without a declaration (driven
    directly: a continuous joint, so without a stroke), holding ``held`` on its task."""
    tmp_path = tmp_path / "arm"
    tmp_path.mkdir()
    (tmp_path / "arm.urdf").write_bytes((FIXTURES / "continuous" / "arm.urdf").read_bytes())
    text = (FIXTURES / "continuous" / "robot.toml").read_text()
    text = text.replace('"../task.toml"', '"task.toml"').replace('"xz"', f'"{axes}"')
    declared = text[: text.index("[actuators.x2]")] + text[text.index("[actuators.x3]") :]
    (tmp_path / "robot.toml").write_text(declared)
    (tmp_path / "task.toml").write_text(TASK.format(held=held, one=one, two=two))
    return str(tmp_path / "robot.toml")


@pytest.mark.parametrize("command", ["study", "cycle", "play"])
def test_a_held_joint_without_a_stroke_names_the_table_that_gives_it_one(tmp_path, capsys, command):
    argv = [command, "--robot", arm(tmp_path)]
    if command == "play":
        argv += ["--html", str(tmp_path / "p.html")]
    else:
        argv += ["--quiet", "--out", str(tmp_path / "out")]
    status, _, lines = run(argv, capsys)
    found = errors(lines)
    assert status == 2 and len(found) == 1, found
    assert "held actuator stick_joint has no finite stroke to sample, [-∞, ∞]" in found[0]
    assert (
        f"{tmp_path / 'arm' / 'robot.toml'}: [actuators.stick_joint] (a table to add, with kind = "
        "\"Identity\" and joint = 'stick_joint'): stroke = [lower, upper] (rad)" in found[0]
    ), found[0]
    assert not (tmp_path / "out").exists()


def test_check_reports_a_held_joint_without_a_stroke_instead_of_aborting(tmp_path, capsys):
    status, out, lines = run(["check", "--robot", arm(tmp_path)], capsys)
    assert status == 2 and not errors(lines), lines
    assert "actuators (values over the joint's range" in out  # the whole screen, not one error
    assert "a study: held actuator stick_joint has no finite stroke" in out


def test_a_declared_held_actuator_without_a_stroke_names_its_own_table(tmp_path, capsys):
    path = arm(tmp_path, held='["x3"]')
    text = Path(path).read_text().replace("stroke = [0.2, 1.1]\n", "")
    Path(path).write_text(text)
    status, _, lines = run(
        ["study", "--robot", path, "--quiet", "--out", str(tmp_path / "o")], capsys
    )
    assert status == 2, lines
    assert f"give it one in {path}: [actuators.x3]: stroke = [lower, upper] (m)" in errors(lines)[0]


def test_too_few_held_actuators_point_at_locked_joints_and_the_joints_to_lock(tmp_path, capsys):
    """A machine whose undeclared joints move freely (a chassis, say) has more redundant degrees
    than its task holds: the message names the task file's held list, ``locked_joints``, the
    robot's file and the joints."""
    path = arm(tmp_path, held='["x3"]', axes="x", one="[2.8]", two="[2.6]")
    for command in (["study", "--quiet", "--out", str(tmp_path / "o")], ["check"]):
        status, out, lines = run([command[0], "--robot", path, *command[1:]], capsys)
        message = errors(lines)[0] if command[0] == "study" else out
        assert status == 2, lines
        assert "task.toml: held: task " in message
        assert "holds ['x3'], but arm has n − m = 3 − 1 = 2 redundant degrees" in message
        assert (
            f"or lock the joints the task does not move with locked_joints in {path} (joints "
            "without an actuator declaration: stick_joint)" in message
        ), message


def test_describe_gives_the_tasks_m_with_the_tool_angle(capsys):
    status, out, _ = run(["describe", "--robot", str(PLANAR / "robot.toml")], capsys)
    assert status == 0
    assert "n = 4 joints, task = tool xy + angle (m = 3)" in out


def test_a_kinematic_only_robots_default_study_runs_what_needs_no_masses(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["study", "--robot", str(FIXTURES / "massless" / "robot.toml"), "--quiet"]
    status, printed, lines = run([*argv, "--cycles", "0", "--out", str(out)], capsys)
    assert status == 0, lines
    left_out = [line for line in lines if "leaves out what needs masses" in line]
    assert len(left_out) == 1 and "the energy objective" in left_out[0], lines
    assert "velocity" in printed and (out / "report.json").is_file()


def test_check_shows_task_points_in_the_units_of_the_task_file(capsys):
    """The planar arm's task gives its tool angle in degrees: check shows 30°, not 0.5236."""
    status, out, _ = run(["check", "--robot", str(PLANAR / "robot.toml")], capsys)
    assert status == 0
    assert "  a at [1900 mm, 0 mm, 30°]: reached" in out


def test_a_rotary_held_start_is_shown_in_degrees(capsys):
    """The planar arm holds a turning joint: play names its start in degrees, as every other
    message does, not in rad beside them."""
    robot, cycle = _load_task(load_robot(PLANAR / "robot.toml"), None)
    args = parser().parse_args(["play", "--start", "x1=-0.1336"])
    _, label = _play_motion(robot, cycle, cycle.segments[0], VELOCITY, args)
    assert label.startswith("x1 = -7.655°, one of 2 start configurations there"), label


def test_the_cycle_of_turning_actuators_gives_its_velocity_peaks_in_rad_per_second(
    tmp_path, capsys
):
    argv = ["cycle", "--robot", str(PLANAR / "robot.toml"), "--cycles", "1", "--quiet"]
    status, out, lines = run([*argv, "--strategy", "free", "--out", str(tmp_path / "o")], capsys)
    assert status == 0, lines
    assert "m²/s²" not in out
    assert re.search(r"whole-cycle improved start: .*, peak ẋᵀẋ [0-9.]+ rad²/s²", out), out


def test_limit_avoidance_on_an_unbounded_actuator_computes_no_invalid_value(tmp_path):
    """Gradient projection pulls each actuator toward its mid-stroke; an unbounded one (the
    arm's continuous stick joint) has none and is left free, without inf − inf on the way (numpy
    said so in "invalid value encountered in add" notes)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(arm(tmp_path))
    space = actuator_space(robot, np.array([0.3, -0.5, 0.4]))
    with np.errstate(all="raise"):
        z = GradientProjection().null_space(space)
    assert np.all(np.isfinite(z)) and z[0, 1] == 0.0 and z[0, 0] != 0.0


def test_a_load_pressure_beyond_the_circuits_physics_is_flagged_not_reported(tmp_path):
    """The excavator's M_H-weighted law lifting to the truck (2-3) leaves the bucket's stroke
    towards its linkage's toggle, where the quasi-static model asks over 30,000 bar of the stick
    cylinder: the table and the report page flag it, and print no such pressure, nor the pump
    energies that follow it, nor their excess over an energy bound."""
    excavator = load_robot("excavator")
    text = excavator.task_file.read_text().replace('["1-2", "2-3", "3-1"]', '["2-3"]')
    (tmp_path / "task.toml").write_text(text)
    cycle = WorkCycle.from_toml(tmp_path / "task.toml", dimension=excavator.m)
    study = run_study(
        excavator, cycle, (VELOCITY,), samples=5, bound=False, progress=False, cycles=0
    )
    relief = excavator.circuit().relief / BAR
    rows = {r["strategy"]: r["hydraulics"] for r in study.report()["comparison"]}
    weighted = rows["M_H-weighted, default start"]
    assert weighted["max_load_pressure_bar"] > 2 * relief and weighted["unphysical"]
    assert not any(
        r["unphysical"] for name, r in rows.items() if name != "M_H-weighted, default start"
    )
    line = next(s for s in hydraulic_table(study).splitlines() if "M_H-weighted" in s)
    pressure = weighted["max_load_pressure_bar"]
    said = f"(!) p_L {pressure:.0f} bar, over 2 × the relief 300 bar: no circuit delivers it (a "
    assert said in line, line
    assert f"{weighted['max_load_pressure_bar']:.1f}" not in line
    assert f"{weighted['ls_energy_kj']:.2f}" not in line
    assert f"{weighted['cp_energy_kj']:.2f}" not in line
    page = _hydraulics(study.report()["comparison"], None)
    assert page.count("beyond the circuit's physics") == 3  # p_L, the energies
    assert "above LS bound" not in page  # no energy bound asked for: no column of dashes
    bounded = _hydraulics(study.report()["comparison"], {"1-2": {}})
    assert bounded.count("beyond the circuit's physics") == 5  # and the energies' excess


def test_an_energy_no_supply_could_deliver_is_flagged_not_reported(tmp_path):
    """The crane on a circuit with its relief at 60 bar: load sensing serves 40 bar, the
    constant pressure 50. A motion whose moving cylinders ask more of a supply than it serves
    (p_L by the meter-in model from the motion's own ẋ and F_H) has no energy under it: the
    table says so by how much, the page too, and the other supply's energy stays."""
    text = (bundled_root() / "hiab031" / "robot.toml").read_text()
    table = text[text.index("[hydraulics]") :].replace("relief = 210.0", "relief = 60.0")
    (tmp_path / "low.toml").write_text(table.replace("cp_pressure = 180.0", "cp_pressure = 50.0"))
    robot = load_robot("hiab031", hydraulics=tmp_path / "low.toml")
    task = robot.task_file.read_text().replace('["1-2", "2-3", "3-1"]', '["1-2"]')
    (tmp_path / "task.toml").write_text(task)
    cycle = WorkCycle.from_toml(tmp_path / "task.toml", dimension=robot.m)
    study = run_study(robot, cycle, (VELOCITY,), samples=5, bound=False, progress=False, cycles=0)
    served = {"LS": 40, "CP": 50}  # bar: the relief less the LS margin, and p_S
    circuit = robot.circuit()
    area_a, area_b = circuit.piston_areas, circuit.rod_side_areas
    lines = hydraulic_table(study).splitlines()
    flagged = 0
    for run in study.runs:
        motion, figures = run.trajectory, run.summary()["hydraulics"]
        v = motion.x_dot[0][:, circuit.columns]
        force = motion.forces[0][:, circuit.columns]
        load = np.where(v >= 0, (force + circuit.tank * area_b) / area_a, 0.0)
        load = np.where(v < 0, (circuit.tank * area_a - force) / area_b, load)
        moving = np.where(np.abs(v) > 1e-9, np.maximum(load, circuit.tank), -np.inf).max()
        expected = [s for s, bar in served.items() if moving > bar * BAR]
        assert figures["unserved"] == expected, run.strategy
        line = next(s for s in lines if run.strategy in s)
        for supply in ("LS", "CP"):
            energy = f"{figures[f'{supply.lower()}_energy_kj']:.2f}"
            assert (energy in line) == (supply not in expected), line
        if expected:
            flagged += 1
            assert f"past what {expected[0]} ({served[expected[0]]} bar)" in line
    assert flagged  # the crane's lift and fold ask about 45 bar
    page = _hydraulics(study.report()["comparison"], None)
    assert "past what LS serves" in page


def test_the_playback_draws_every_link_with_its_cylinders_points_inside_mesh_less_hulls(tmp_path):
    """The arm whose meshes are missing, its stick joint locked: every URDF link with a visual
    is in the page's scene, the locked stick among them; a link without a drawable visual is
    the hull of its origin, the joints it carries and the cylinders' points on it, posed with
    the link, so that the cylinders sit on their links."""
    folder = tmp_path / "arm"
    folder.mkdir()
    (folder / "arm.urdf").write_bytes((FIXTURES / "meshes" / "arm.urdf").read_bytes())
    text = (FIXTURES / "meshes" / "robot.toml").read_text().replace('task = "../task.toml"\n', "")
    locked = text.replace(
        'task_axes = "xz"', 'task_axes = "xz"\nlocked_joints = {stick_joint = -1.4}'
    )
    (folder / "robot.toml").write_text(locked)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(folder / "robot.toml")
    q0 = np.array([0.3, 0.4])
    y0 = actuator_space(robot, q0).y[0].tolist()
    (folder / "t.toml").write_text(
        f'name = "t"\nspeed = 0.2\nsegments = ["1-2"]\n[points]\n1 = {y0}\n'
        f"2 = {[y0[0], y0[1] + 0.05]}\n"
    )
    segment = WorkCycle.from_toml(folder / "t.toml", dimension=2).segments[0]
    motion = simulate(robot, VELOCITY.resolver, segment, q0[None])
    recording = Recording()
    Playback(motion).draw(meshcat.Visualizer(window=recording))
    commands = [umsgpack.unpackb(c) for c in recording.commands]
    drawn = {
        c["path"].rsplit("/links/", 1)[1]: c["object"]["geometries"][0]
        for c in commands
        if c["type"] == "set_object" and "/links/" in c["path"]
    }
    posed = {
        c["path"].rsplit("/links/", 1)[1]: np.array(c["matrix"], dtype=float).reshape(4, 4).T
        for c in commands
        if c["type"] == "set_transform" and "/links/" in c["path"]
    }
    # boom and stick name missing meshes, base has no visual: hulls; the telescope's box
    assert sorted(drawn) == ["hulls/base", "hulls/boom", "hulls/stick", "visuals/telescope_0"]
    on_links = {  # the points each hull must hold, in its link's frame (m)
        "base": [[0, 0, 0], [0, 0, 1], [0.5, 0, 0.4]],  # boom joint, x1's base
        "boom": [[0, 0, 0], [2, 0, 0], [0.9, 0, -0.2]],  # stick joint, x1's rod (x2 locked)
        "stick": [[0, 0, 0], [0.7, 0, 0]],  # telescope joint
    }
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, q0)
    for link, points in on_links.items():
        vertices = np.frombuffer(
            drawn[f"hulls/{link}"]["data"]["attributes"]["position"]["array"].data, np.float32
        )
        inside = Delaunay(vertices.reshape(-1, 3)).find_simplex(np.array(points, dtype=float))
        assert np.all(inside >= 0), link
        pose = posed[f"hulls/{link}"]
        np.testing.assert_allclose(pose, data.oMf[model.getFrameId(link)].homogeneous, atol=1e-9)
    # the cylinder x1 runs from its base on the base's hull to its rod on the boom's
    base, rod = robot.actuators["x1"].ends(robot.kinematics(q0[None]))
    np.testing.assert_allclose(posed["hulls/base"] @ [0.5, 0, 0.4, 1], [*base[0], 1], atol=1e-9)
    np.testing.assert_allclose(posed["hulls/boom"] @ [0.9, 0, -0.2, 1], [*rod[0], 1], atol=1e-9)


def test_describe_gives_the_mid_range_state_in_degrees_and_mm(capsys):
    status, out, _ = run(["describe", "--robot", str(PLANAR / "robot.toml")], capsys)
    assert status == 0
    assert "at mid-range q = [0°, 0°, 0°, 0°]: x = [0°, 0°, 0°, 0°], y = [2800 mm, 0 mm, 0°]" in out
    status, out, _ = run(["describe"], capsys)
    assert "at mid-range q = [98.6°, 74.97°, 725 mm]: x = [1155 mm, 1091 mm, 545 mm]" in out


def test_the_report_page_gives_turning_actuators_velocity_peaks_in_rad_per_second(tmp_path, capsys):
    argv = ["study", "--robot", str(PLANAR / "robot.toml"), "--objective", "velocity"]
    argv += ["--cycles", "0", "--samples", "10", "--quiet", "--out", str(tmp_path / "o")]
    status, out, lines = run(argv, capsys)
    assert status == 0, lines
    page = (tmp_path / "o" / "index.html").read_text()
    assert "peak ẋᵀẋ (rad²/s²)" in page and "m²/s²" not in out


def test_a_mix_of_turning_and_sliding_actuators_gives_velocity_peaks_in_both_units():
    """The slewing crane's ẋᵀẋ adds the slew's (rad/s)² to the cylinders' (m/s)²: its unit
    says so (it was labelled m²/s²); the crane's alone is m²/s², the Panda's rad²/s², and the
    kinetic-energy objective's J on every one."""
    units = {}
    for name in ("hiab031", "hiab031_slewing", "panda"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the Panda's joints are driven directly
            actuators = load_robot(name).actuators
        units[name] = (VELOCITY.unit_of(actuators), ENERGY.unit_of(actuators))
    assert units == {
        "hiab031": ("m²/s²", "J"),
        "hiab031_slewing": ("m²/s²; rad²/s² for slew", "J"),
        "panda": ("rad²/s²", "J"),
    }


def test_a_round_off_is_shown_as_zero_not_as_a_tiny_number():
    """A continuous joint's stroke written [0, 2π] read back as [1.8e-15, 2π] was shown as
    "[1.033e-13°, 360°]"; values below a converged residual, 1e-12 in SI units, are 0."""
    assert span(1.8e-15, 2 * np.pi, "rad") == "[0°, 360°]"
    assert amount(-1.2e-72, "rad") == "0°" and amount(-1e-13, "m") == "0 mm"
    assert amount(2e-12, "m") == "2e-09 mm" and amount(0.8279, "m") == "827.9 mm"


def test_a_length_of_ten_metres_or_more_is_written_out_in_mm(tmp_path, capsys):
    """A task point 30 m out was shown by check as "[3e+04 mm, -500 mm]": a length of 10 m
    or more is written out to the whole mm, with no power of ten."""
    task = (bundled_root() / "hiab031" / "task.toml").read_text()
    (tmp_path / "t.toml").write_text(task.replace("1 = [3.5, -0.5]", "1 = [30.0, -0.5]"))
    status, out, _ = run(["check", "--task", str(tmp_path / "t.toml")], capsys)
    assert status == 2 and "  1 at [30000 mm, -500 mm]: NOT reached" in out.splitlines(), out
    # the points by their names, in the order the cycle meets them, with the payload's share
    assert out.splitlines()[-5:-1] == [
        "task points:",
        "  1 at [30000 mm, -500 mm]: NOT reached",
        "  2 at [1000 mm, -500 mm]: reached",
        "  3 at [2250 mm, 3000 mm]: reached",
    ], out
    assert "masses: on every moving link, 316.0 kg in all, of which payload 100.0 kg" in out
    # the Panda's base, panda_link0 (0.63 kg), is fixed to the ground: not on a moving link
    _, out, _ = run(["check", "--robot", "panda"], capsys)
    assert "masses: on every moving link, 16.8 kg in all, of which payload 0.0 kg" in out, out
    assert amount(96.1263, "m") == "96126 mm" and amount(9.99996, "m") == "10000 mm"
    assert amount(1100.0, "m") == "1100000 mm" and amount(1e300, "m") == "1e+303 mm"


def test_a_cylinder_point_in_mm_names_the_number_and_the_fix(tmp_path, capsys):
    """A rod pin written in mm in robot.toml: the line named the pin only as a cut excerpt
    of its table and the general shape; it names the coordinate out of range and the fix."""
    path = arm(tmp_path)
    text = Path(path).read_text().replace("xyz = [0.9, 0.0, -0.2]", "xyz = [900.0, 0.0, -200.0]")
    Path(path).write_text(text)
    status, _, lines = run(["check", "--robot", path], capsys)
    found = errors(lines)
    assert status == 2 and len(found) == 1, found
    assert "[actuators.x1] rod = " in found[0]
    assert (
        "xyz must be within ±100 m of the link's frame: 900 m is beyond; did you give mm? "
        "1 m = 1000 mm (the cylinder's rod point)" in found[0]
    ), found[0]


def test_a_broken_urdf_is_named_by_its_path_and_its_xml_by_the_line(tmp_path, capsys):
    """A URDF was named by its file name alone, and bad XML with the parser's "(<string>,
    line 3)" after the message: the line names the file by its path, and bad XML by its line,
    once."""
    path = tmp_path.resolve() / "sub" / "arm.urdf"
    path.parent.mkdir()
    path.write_text('<robot name="a">\n  <link name="b">\n</robot>\n')
    status, _, lines = run(["describe", "--robot", str(path)], capsys)
    assert status == 2 and lines == [
        f"redundancy: error: {path} line 3: not readable XML: Opening and ending tag mismatch: "
        "link line 2 and robot"
    ]
    path.write_text('<robot name="a">\n  <joint name="j" type="fixed"/>\n</robot>\n')
    status, _, lines = run(["describe", "--robot", str(path)], capsys)
    assert status == 2 and lines == [
        f"redundancy: error: {path}: joint 'j': it needs <parent link=\"...\"/>"
    ]


def test_a_held_value_with_two_start_configurations_is_said_so_in_play(tmp_path, capsys):
    """The slewing 3R arm's line: the improved start's held value is reached on both elbows;
    played from that value, the motion is of the elbow inverse kinematics picks, whose peak is
    not the search's (0.158 against 0.0739 rad²/s²), and the playback says so and how to play
    the search's own. The crane, one configuration a value, is played without the words."""
    data = Path(__file__).parent / "data" / "slewing3r"
    argv = ["play", "--robot", str(data / "robot.toml"), "--task", str(data / "line.toml")]
    status, out, _ = run([*argv, "--x3init", "0.7881", "--html", str(tmp_path / "a.html")], capsys)
    assert status == 0
    assert "one of 2 start configurations there (assembly branches)" in out
    assert "--best plays the improved start's" in out
    status, out, _ = run(["play", "--x3init", "1.0", "--html", str(tmp_path / "b.html")], capsys)
    assert status == 0 and "start configurations" not in out
