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

import ast
import importlib
from pathlib import Path
from typing import TYPE_CHECKING

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


def _exports() -> dict[str, str]:
    """Each public name and the module it comes from, read from the imports above."""
    tree = ast.parse(Path(__file__).read_text(encoding="utf-8"))
    block = next(node for node in tree.body if isinstance(node, ast.If))
    return {
        alias.name: str(node.module)
        for node in block.body
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
    }


_EXPORTS = _exports()
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'redundancy' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value  # imported once
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
