"""Loading robots: bundled files, user-defined actuator kinds, and every bad input named."""

import importlib.util
import re
import site
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from declarations import write_transmissions
from geared import GearedMotor
from joint_space import fk, mass

from redundancy import (
    InvalidInputError,
    LinearCylinder,
    Prismatic,
    RobotDescriptionError,
    actuator_space,
    bundled_robots,
    load_robot,
)
from redundancy.model.loading import bundled_root

CRANE_URDF = bundled_root() / "hiab031" / "hiab031.urdf"
REPO = Path(__file__).resolve().parents[1]


def crane_variant(tmp_path, old, new):
    text = CRANE_URDF.read_text()
    assert old in text
    path = tmp_path / "variant.urdf"
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.filterwarnings("ignore:joints without an actuator declaration")
def test_every_bundled_robot_loads_and_its_files_exist():
    assert bundled_robots() == ["excavator", "hiab031", "hiab031_slewing", "panda"]
    for name in bundled_robots():
        robot = load_robot(name)
        folder = bundled_root() / name
        assert (folder / "README.md").is_file()
        assert robot.task_file is not None and robot.task_file.is_file()
        assert robot.n == len(robot.actuators) and 1 <= robot.m < robot.n
    assert (load_robot("panda").n, load_robot("hiab031_slewing").n) == (7, 4)


def test_committed_crane_urdfs_are_what_the_generator_writes():
    spec = importlib.util.spec_from_file_location(
        "generate", REPO / "redundancy" / "robots" / "hiab031" / "generate.py"
    )
    generate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generate)
    assert len(generate.OUTPUTS) == 2
    for path, slewing in generate.OUTPUTS.items():
        assert path.read_text() == generate.urdf(slewing), path.name


def test_unknown_robot_lists_the_bundled_ones():
    with pytest.raises(RobotDescriptionError, match=r"unknown robot 'hiab32'.*hiab031"):
        load_robot("hiab32")


def test_a_folder_without_a_robot_description_is_named_as_one(tmp_path):
    with pytest.raises(RobotDescriptionError, match=r"is a folder without a robot.toml.*hiab031"):
        load_robot(tmp_path)


def test_malformed_urdf_is_named(tmp_path):
    path = crane_variant(tmp_path, "</robot>", "")
    with pytest.raises(RobotDescriptionError, match="not readable XML"):
        load_robot(path)
    path = crane_variant(tmp_path, '<parent link="boom1"/>', '<parent link="nowhere"/>')
    with pytest.raises(RobotDescriptionError, match="not a valid URDF"):
        load_robot(path)


def test_actuator_on_a_missing_joint_lists_the_joints(tmp_path):
    path = crane_variant(tmp_path, '<joint name="boom2_joint"/>', '<joint name="boom3_joint"/>')
    with pytest.raises(RobotDescriptionError, match=r"'boom3_joint'.*boom1_joint, boom2_joint"):
        load_robot(path)


def test_actuator_on_a_missing_link_lists_the_links(tmp_path):
    path = crane_variant(tmp_path, '<attachment link="column"', '<attachment link="colum"')
    with pytest.raises(RobotDescriptionError, match=r"link 'colum'.*links: .*column"):
        load_robot(path)


def test_a_joint_driven_twice_is_refused(tmp_path):
    path = crane_variant(tmp_path, '<joint name="boom2_joint"/>', '<joint name="boom1_joint"/>')
    with pytest.raises(RobotDescriptionError, match="'boom1_joint' is driven twice"):
        load_robot(path)


def test_an_actuator_named_like_a_joint_driven_directly_is_refused(tmp_path):
    """A joint no actuator drives is driven directly by an actuator named after it: a declared
    actuator of that name, on another joint, would make two actuators of one name."""
    path = crane_variant(tmp_path, 'name="x2"', 'name="telescope_joint"')
    text = path.read_text()
    path.write_text(text[: text.index('<transmission name="x3">')] + "</robot>\n")
    with pytest.raises(
        RobotDescriptionError,
        match=r"actuator 'telescope_joint' drives joint 'boom2_joint' and is named like joint "
        r"'telescope_joint', which no actuator drives",
    ):
        load_robot(path)


def test_unknown_actuator_kind_lists_the_known_ones(tmp_path):
    path = crane_variant(tmp_path, "redundancy/Prismatic", "redundancy/Telescope")
    with pytest.raises(RobotDescriptionError, match=r"Telescope.*redundancy/Prismatic"):
        load_robot(path)


def test_a_cylinder_on_a_prismatic_map_of_a_revolute_joint_is_refused():
    model = load_robot("hiab031").model
    with pytest.raises(RobotDescriptionError, match="not prismatic"):
        Prismatic("x", "boom1_joint").bind(model)


@pytest.mark.parametrize(
    "q, message",
    [([1.0, 1.0], r"shape \(3,\)"), ([1.0, np.nan, 0.5], "NaN"), (np.ones((2, 2, 3)), "shape")],
)
def test_bad_configurations_are_named(crane, q, message):
    with pytest.raises(InvalidInputError, match=message):
        actuator_space(crane, q)


@pytest.mark.parametrize("payload", [-1.0, float("nan")])
def test_bad_payload_is_refused(payload):
    with pytest.raises(InvalidInputError, match="payload"):
        load_robot("hiab031", payload=payload)


def test_urdf_without_declarations_drives_every_joint_directly(tmp_path):
    text = CRANE_URDF.read_text()
    path = tmp_path / "bare.urdf"
    path.write_text(write_transmissions(text, []))
    with pytest.warns(UserWarning, match="boom1_joint, boom2_joint, telescope_joint"):
        robot = load_robot(path)
    q = (robot.lower + robot.upper) / 2
    np.testing.assert_array_equal(actuator_space(robot, q).A[0], np.eye(3))


def test_actuator_map_written_from_python_loads_back(tmp_path, crane):
    path = tmp_path / "rewritten.urdf"
    path.write_text(write_transmissions(CRANE_URDF.read_text(), crane.actuators.maps))
    again = load_robot(path)
    q = (crane.lower + crane.upper) / 2
    for a, b in zip(crane.actuators, again.actuators):
        assert (type(a), a.name, a.joint, a.lower, a.upper) == (
            type(b),
            b.name,
            b.joint,
            b.lower,
            b.upper,
        )
    np.testing.assert_array_equal(actuator_space(again, q).A, actuator_space(crane, q).A)


def test_a_users_own_actuator_kind_plugs_in_through_the_urdf(tmp_path, crane):
    maps = [a for a in crane.actuators if a.name != "x1"]
    maps.append(GearedMotor("slew", "boom1_joint", -10, 10, ratio=50.0))
    path = tmp_path / "geared.urdf"
    path.write_text(write_transmissions(CRANE_URDF.read_text(), maps))
    robot = load_robot(path)
    assert isinstance(robot.actuators["slew"], GearedMotor)
    space = actuator_space(robot, (robot.lower + robot.upper) / 2)
    assert space.A[0, 0, 0] == 50.0
    assert isinstance(robot.actuators["x2"], LinearCylinder)


def test_bundled_robots_load_after_a_plain_install_elsewhere(tmp_path):
    """``pip install .`` (not editable) into a fresh folder, then load from another directory.
    Built as `scripts/env.sh` builds the editable install, with the environment's own build
    requirements: the same compiler command line, so the compiled core is not compiled again."""
    target = tmp_path / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--target",
            str(target),
            str(REPO),
        ],
        check=True,
        capture_output=True,
    )
    code = (
        "import redundancy\n"
        "assert 'site' in redundancy.__file__, redundancy.__file__\n"
        "for name in redundancy.bundled_robots():\n"
        "    r = redundancy.load_robot(name)\n"
        "    print(name, r.n, r.m, r.task_file.is_file())\n"
    )
    # Without site (-S), so that no editable install's import hook runs first: the installed
    # copy, then the environment's packages and Pinocchio's.
    paths = [target, *map(Path, site.getsitepackages()), Path(pin.__file__).parents[1]]
    run = subprocess.run(
        [sys.executable, "-S", "-c", code],
        cwd=tmp_path,
        env={"PYTHONPATH": ":".join(map(str, paths)), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    installed = [line.split() for line in run.stdout.splitlines()]
    assert [row[0] for row in installed] == bundled_robots()
    assert ["hiab031", "3", "2", "True"] in installed
    assert all(row[3] == "True" for row in installed)


def test_the_install_puts_no_folder_above_the_repository_on_the_import_path(tmp_path):
    """An editable install adds the repository to ``sys.path``, never a folder above it: a
    module lying beside the clone would run at every start of the interpreter."""
    run = subprocess.run(
        [sys.executable, "-c", "import sys; print('\\n'.join(sys.path))"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=True,
    )
    paths = [Path(line).resolve() for line in run.stdout.splitlines() if line]
    above = [str(path) for path in paths if path != REPO and REPO.is_relative_to(path)]
    assert not above, above


def test_a_joint_named_like_the_tool_link_is_not_taken_for_it(tmp_path):
    """URDFs often name a fixed joint after the link it carries; the tool is the link."""
    text = CRANE_URDF.read_text().replace('<joint name="tool_mount"', '<joint name="tool"')
    (tmp_path / "crane.urdf").write_text(text)
    (tmp_path / "robot.toml").write_text(
        'urdf = "crane.urdf"\ntool_frame = "tool"\ntask_axes = "xz"\npayload = 100.0\n'
    )
    renamed, crane = load_robot(tmp_path / "robot.toml"), load_robot("hiab031")
    q = np.array([[1.7, 1.0, 0.5], [2.0, 0.6, 0.1]])
    np.testing.assert_allclose(fk(renamed, q), fk(crane, q), atol=1e-12)
    np.testing.assert_allclose(mass(renamed, q), mass(crane, q), atol=1e-9)


def test_an_inertia_on_the_edge_of_a_body_loads_as_a_file_rounds_it(tmp_path):
    """A slender boom's principal moments lie on the edge of the triangle inequality (0 + iyy =
    izz): with izz rounded up by 8e-9 of itself the crane loads as before (izz, about an axis
    normal to the joints' axes, leaves M alone); 2e-4 is refused."""
    crane = load_robot(CRANE_URDF)
    rounded = load_robot(crane_variant(tmp_path, 'izz="17.0666666666667"', 'izz="17.0666668"'))
    q = (crane.lower + crane.upper) / 2
    np.testing.assert_allclose(mass(rounded, q), mass(crane, q), rtol=1e-8)
    beyond = crane_variant(tmp_path, 'izz="17.0666666666667"', 'izz="17.07"')
    with pytest.raises(RobotDescriptionError, match=r"link 'boom1' <inertia .* izz=\"17.07\"/> is"):
        load_robot(beyond)


def test_a_robot_toml_reached_through_a_symbolic_link_reads_from_its_own_folder(tmp_path):
    """A robot.toml linked from elsewhere names its URDF, task and hydraulics relative to the
    folder it is in, not to the link's: the same robot loads."""
    link = tmp_path / "elsewhere" / "robot.toml"
    link.parent.mkdir()
    link.symlink_to(bundled_root() / "hiab031" / "robot.toml")
    linked, bundled = load_robot(link), load_robot("hiab031")
    assert linked.actuators.names == bundled.actuators.names
    assert linked.task_file == bundled.task_file
    assert (linked.hydraulics is None) == (bundled.hydraulics is None)
    q = (bundled.lower + bundled.upper) / 2
    np.testing.assert_array_equal(fk(linked, q), fk(bundled, q))


def test_a_folder_named_like_a_bundled_robot_is_loaded_with_a_word(tmp_path, monkeypatch):
    """A bare name is a folder of the working directory first, where one holds a robot.toml
    (a user's edited copy of a bundled robot, say), and then a bundled robot: where it is both,
    the folder's robot loads and a warning says it is not the bundled one. A path that says it
    is one loads without a word."""
    import shutil

    shutil.copytree(bundled_root() / "hiab031", tmp_path / "hiab031")
    toml = tmp_path / "hiab031" / "robot.toml"
    bundled = load_robot("hiab031")
    toml.write_text(
        re.sub(r"(?m)^payload = .*$", f"payload = {bundled.payload + 1}", toml.read_text())
    )
    monkeypatch.chdir(tmp_path)
    with pytest.warns(UserWarning, match=r"'hiab031' is the folder .*hiab031 .*not the bundled"):
        copy = load_robot("hiab031")
    assert copy.payload == bundled.payload + 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_robot("./hiab031")
        load_robot(Path("hiab031"))
