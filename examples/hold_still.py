"""M_H and the actuator forces that hold the HIAB 031 crane still at one configuration."""

import numpy as np

from redundancy import actuator_space, load_robot

robot = load_robot("hiab031", payload=100.0)
q = np.array([np.radians(100.0), np.radians(60.0), 0.7])  # q1, q2 (rad), d3 (m)
space = actuator_space(robot, q)
holding = space.forces(np.zeros((1, robot.n)))  # F_H = M_H ẍ + N_H with ẍ = 0, ẋ = 0

np.set_printoptions(precision=3, suppress=True)
print(f"tool at y = {space.y[0]} m, actuators at x = {space.x[0]} m")
print(f"M_H (kg) =\n{space.M_H[0]}")
for name, force in zip(robot.actuators.names, holding[0]):
    print(f"{name}: {force / 1000:8.3f} kN")
