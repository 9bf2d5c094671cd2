"""Kinematic redundancy resolution of manipulators driven by linear hydraulic actuators.

Pinocchio gives the joint-space model of a URDF; an actuator map turns it into hydraulic
coordinates x (cylinder lengths, telescope strokes), in which redundancy is resolved. The
package is layered (see docs/architecture.md): `model` (what the machine is), `resolution` (what
it should do now), `planning` (what it does over time), `study` (what the user asked for),
`viz`; the public API is re-exported here, flat.

Every name is imported when first used (PEP 562): ``import redundancy`` itself is quick, so that
the command line sets up its handling of Ctrl-C before the heavy libraries load. The imports
below are what type checkers read, and the one list of the public names.
"""

from __future__ import annotations

TYPE_CHECKING = False  # typing's flag, which type checkers read as true, without typing's import
if TYPE_CHECKING:
    from redundancy.errors import (
        InvalidInputError,
        RedundancyError,
        RobotDescriptionError,
        SingularConfigurationError,
        UnreachableError,
    )
    from redundancy.model.actuators import (
        ActuatorMap,
        ActuatorSet,
        Identity,
        LinearCylinder,
        Prismatic,
    )
    from redundancy.model.hydraulics import (
        Circuit,
        ConstantPressure,
        Cylinder,
        Flows,
        LoadSensing,
        Supply,
    )
    from redundancy.model.kinematics import Kinematics
    from redundancy.model.linkage import LinkageCylinder
    from redundancy.model.loading import bundled_robots, load_robot
    from redundancy.model.parameters import Choice, Number, Point
    from redundancy.model.robot import Robot
    from redundancy.planning.angles import ToolAngleRobot, with_tool_angle
    from redundancy.planning.bound import GlobalOptimum, global_optimum
    from redundancy.planning.cycles import (
        CyclePlan,
        PeriodicOptimum,
        Repetition,
        ReturnMap,
        improved_cycle_start,
        periodic_optimum,
        plan_cycle,
        repeat,
        return_map,
    )
    from redundancy.planning.ik import configuration_at, inverse_kinematics
    from redundancy.planning.integral_optimum import (
        EnergyOptimum,
        IntegralOptimum,
        energy_optimum,
        integral_optimum,
    )
    from redundancy.planning.integrate import Trajectory, simulate
    from redundancy.planning.motions import simulate_path
    from redundancy.planning.starts import (
        Sample,
        SearchResult,
        default_start,
        improved_start,
        improved_starts,
    )
    from redundancy.planning.tasks import Arc, Line, Polyline, Segment, WorkCycle
    from redundancy.planning.time_scaling import Retimed, shortest_duration
    from redundancy.resolution.laws import (
        Controller,
        GradientProjection,
        MinFlow,
        MinKineticEnergy,
        MinVelocityNorm,
        Resolver,
        State,
        Step,
    )
    from redundancy.resolution.limits import Limits, Violation
    from redundancy.resolution.objectives import (
        CP_ENERGY,
        ENERGY,
        FLOW,
        LS_ENERGY,
        VELOCITY,
        Objective,
    )
    from redundancy.resolution.state import ActuatorSpace, actuator_space
    from redundancy.study.check import Check, check
    from redundancy.study.cycles import CycleStudy, run_cycle
    from redundancy.study.families import MapFamily, read_family
    from redundancy.study.maps import design_map
    from redundancy.study.study import Study, run_study


_EXPORTS: dict[str, str] = {}  # each public name and its module, once first asked for


def _exports() -> dict[str, str]:
    """Each public name and the module it comes from, read from the imports above when a name
    is first asked for (parsing this file at import would cost the command's start
    milliseconds before it handles Ctrl-C)."""
    if not _EXPORTS:
        import ast

        with open(__file__, encoding="utf-8") as source:
            tree = ast.parse(source.read())
        block = next(node for node in tree.body if isinstance(node, ast.If))
        _EXPORTS.update(
            (alias.name, str(node.module))
            for node in block.body
            if isinstance(node, ast.ImportFrom)
            for alias in node.names
        )
    return _EXPORTS


def __getattr__(name: str):
    if name == "__all__":
        return sorted(_exports())
    if name not in _exports():
        raise AttributeError(f"module 'redundancy' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_exports()[name]), name)
    globals()[name] = value  # imported once
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_exports()})
