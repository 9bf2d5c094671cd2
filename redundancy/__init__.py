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
from redundancy.robot import Kinematics, Robot, bundled_robots, load_robot

__all__ = [
    "ActuatorMap",
    "ActuatorSet",
    "ActuatorSpace",
    "Identity",
    "InvalidInputError",
    "Kinematics",
    "LinearCylinder",
    "Prismatic",
    "RedundancyError",
    "Robot",
    "RobotDescriptionError",
    "SingularConfigurationError",
    "UnreachableError",
    "actuator_space",
    "bundled_robots",
    "load_robot",
]
