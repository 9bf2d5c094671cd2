"""The bundled excavator: its URDF is the generator's, its geometry is its source's, and the
paper's study holds on it (the improved start beats the default start on every segment)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from redundancy import VELOCITY, actuator_space, load_robot
from redundancy.planning.tasks import WorkCycle
from redundancy.study.study import run_study

FOLDER = Path(__file__).parents[1] / "redundancy" / "robots" / "excavator"


def generator():
    spec = importlib.util.spec_from_file_location("generate", FOLDER / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def excavator():
    return load_robot("excavator")


def test_committed_urdf_is_what_the_generator_writes():
    generate = generator()
    assert generate.OUTPUT.read_text() == generate.urdf()


def test_cylinder_lengths_at_the_reference_pose_are_the_sources_within_1_mm(excavator):
    """The source's reference pose (boom 30°, stick −60°, bucket 70°) has its pistons at 0.3399,
    0.4342 and 0.5936 m of travel; with rods of 1.336, 1.147 and 0.8656 m these are the lengths
    between the pins, through the bucket's four-bar on the declared branch."""
    x = actuator_space(excavator, np.radians([30.0, -60.0, 70.0])).x[0]
    np.testing.assert_allclose(x, [0.3399 + 1.336, 0.4342 + 1.147, 0.5936 + 0.8656], atol=1e-3)


def test_joint_limits_map_onto_stroke_limits(excavator):
    middle = (excavator.lower + excavator.upper) / 2
    for i, actuator in enumerate(excavator.actuators):
        ends = np.repeat(middle[None], 2, axis=0)
        ends[:, i] = excavator.lower[i], excavator.upper[i]
        x = actuator_space(excavator, ends).x[:, i]
        np.testing.assert_allclose(sorted(x), [actuator.lower, actuator.upper], atol=1e-9)


def test_improved_start_keeps_every_stroke_and_beats_the_default_start(excavator):
    cycle = WorkCycle.from_toml(excavator.task_file, dimension=excavator.m)
    study = run_study(
        excavator, cycle, (VELOCITY,), samples=20, bound=False, progress=False, cycles=0
    )
    for segment in cycle.segments:
        runs = {r.strategy: r.trajectory for r in study.runs if r.segment == segment.name}
        improved = runs["improved, velocity objective"]
        default = runs["unweighted, default start"]
        assert improved.within_limits[0], segment.name
        assert improved.peak_velocity_norm[0] <= default.peak_velocity_norm[0], segment.name


def test_the_searches_hold_the_excavators_bucket_unless_told_otherwise(excavator):
    """Without ``held``, a search, the default start and the bound hold what a work cycle
    holds: the task's actuators (the bucket), or the last n − m; they held "x3", the crane's
    telescope, which the excavator has not. A cycle iterates over its segments in order."""
    from redundancy import default_start, global_optimum, improved_start

    cycle = WorkCycle.from_toml(excavator.task_file, dimension=excavator.m)
    assert cycle.held == ("bucket",) and [s.name for s in cycle] == ["1-2", "2-3", "3-1"]
    segment = cycle["1-2"]
    assert improved_start(excavator, segment, VELOCITY).held == ("bucket",)
    assert improved_start(excavator, cycle, VELOCITY).held == ("bucket",)
    values, q = default_start(excavator, segment)
    assert actuator_space(excavator, q).x[0, 2] == pytest.approx(values[0], abs=1e-9)
    assert values == pytest.approx(default_start(excavator, segment, "bucket")[0], abs=0)
    assert global_optimum(excavator, segment, VELOCITY, grids=(8,)).held == "bucket"
