"""Kinematic redundancy resolution of manipulators driven by linear hydraulic actuators.

Pinocchio gives the joint-space model of a URDF; an actuator map turns it into hydraulic
coordinates x (cylinder lengths, telescope strokes), in which redundancy is resolved. The
package is layered (see docs/architecture.md): `model` (what the machine is), `resolution` (what
it should do now), `planning` (what it does over time), `study` (what the user asked for),
`viz`; the public API is re-exported here, flat.
"""

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
    CycleMotion,
    CyclePlan,
    CycleSearch,
    PeriodicOptimum,
    Repetition,
    ReturnMap,
    improved_cycle_start,
    periodic_optimum,
    plan_cycle,
    repeat,
    return_map,
    simulate_cycle,
)
from redundancy.planning.energy_bound import EnergyOptimum, energy_optimum
from redundancy.planning.ik import configuration_at, inverse_kinematics
from redundancy.planning.integrate import Trajectory, simulate
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
    GradientProjection,
    MinFlow,
    MinKineticEnergy,
    MinVelocityNorm,
    Resolver,
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

__all__ = [
    "CP_ENERGY",
    "ENERGY",
    "FLOW",
    "LS_ENERGY",
    "VELOCITY",
    "ActuatorMap",
    "ActuatorSet",
    "ActuatorSpace",
    "Arc",
    "Check",
    "Choice",
    "Circuit",
    "ConstantPressure",
    "CycleMotion",
    "CyclePlan",
    "CycleSearch",
    "CycleStudy",
    "Cylinder",
    "EnergyOptimum",
    "Flows",
    "GlobalOptimum",
    "GradientProjection",
    "Identity",
    "InvalidInputError",
    "Kinematics",
    "Limits",
    "Line",
    "LinearCylinder",
    "LinkageCylinder",
    "LoadSensing",
    "MapFamily",
    "MinFlow",
    "MinKineticEnergy",
    "MinVelocityNorm",
    "Number",
    "Objective",
    "PeriodicOptimum",
    "Point",
    "Polyline",
    "Prismatic",
    "RedundancyError",
    "Repetition",
    "Resolver",
    "Retimed",
    "ReturnMap",
    "Robot",
    "RobotDescriptionError",
    "Sample",
    "SearchResult",
    "Segment",
    "SingularConfigurationError",
    "Step",
    "Study",
    "Supply",
    "ToolAngleRobot",
    "Trajectory",
    "UnreachableError",
    "Violation",
    "WorkCycle",
    "actuator_space",
    "bundled_robots",
    "check",
    "configuration_at",
    "default_start",
    "design_map",
    "energy_optimum",
    "global_optimum",
    "improved_cycle_start",
    "improved_start",
    "improved_starts",
    "inverse_kinematics",
    "load_robot",
    "periodic_optimum",
    "plan_cycle",
    "read_family",
    "repeat",
    "return_map",
    "run_cycle",
    "run_study",
    "shortest_duration",
    "simulate",
    "simulate_cycle",
    "with_tool_angle",
]
