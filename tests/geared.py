"""A user's own actuator kind, as the docs write one: a rotary motor through a gear."""

import numpy as np

from redundancy import ActuatorMap
from redundancy.model.parameters import Number


class GearedMotor(ActuatorMap):
    """x = ratio · q of its joint (rad of the motor); A's row is ratio at the joint."""

    rotary = True
    parameters = (Number("ratio", "motor turns per joint turn"),)

    def __init__(self, name, joint, lower=-np.inf, upper=np.inf, ratio=1.0):
        super().__init__(name, joint, lower, upper)
        self.ratio = ratio

    def evaluate(self, kinematics):
        row = np.zeros_like(kinematics.q)
        row[:, self.index] = self.ratio
        return self.ratio * kinematics.q[:, self.index], row

    def rate(self, kinematics):
        return np.zeros_like(kinematics.q)
