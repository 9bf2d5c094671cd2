"""Kinematic redundancy resolution of manipulators driven by linear hydraulic actuators.

Pinocchio gives the joint-space model of a URDF; an actuator map turns it into hydraulic
coordinates x (cylinder lengths, telescope strokes), in which redundancy is resolved.
"""

from redundancy.actuator_space import ActuatorSpace, actuator_space
from redundancy.actuators import ActuatorMap, ActuatorSet, Identity, LinearCylinder, Prismatic
from redundancy.errors import (
    InvalidInputError,
    RedundancyError,
    RobotDescriptionError,
    SingularConfigurationError,
    UnreachableError,
)
from redundancy.initial_configuration import SearchResult, default_start, improved_start
from redundancy.objectives import ENERGY, VELOCITY, Objective
from redundancy.resolvers import GradientProjection, MinKineticEnergy, MinVelocityNorm, Resolver
from redundancy.robot import Kinematics, Robot, bundled_robots, load_robot
from redundancy.simulate import Trajectory, simulate
from redundancy.study import Study, run_study
from redundancy.tasks import Segment, WorkCycle

__all__ = [
    "ENERGY",
    "VELOCITY",
    "ActuatorMap",
    "ActuatorSet",
    "ActuatorSpace",
    "GradientProjection",
    "Identity",
    "InvalidInputError",
    "Kinematics",
    "LinearCylinder",
    "MinKineticEnergy",
    "MinVelocityNorm",
    "Objective",
    "Prismatic",
    "RedundancyError",
    "Resolver",
    "Robot",
    "RobotDescriptionError",
    "SearchResult",
    "Segment",
    "SingularConfigurationError",
    "Study",
    "Trajectory",
    "UnreachableError",
    "WorkCycle",
    "actuator_space",
    "bundled_robots",
    "default_start",
    "improved_start",
    "load_robot",
    "run_study",
    "simulate",
]
