"""Seeded random states for the tests."""

import numpy as np


def random_configurations(robot, count, seed, margin=0.0):
    """``count`` configurations uniformly inside the joint limits, shrunk by ``margin`` of the
    range at each end."""
    rng = np.random.default_rng(seed)
    span = robot.upper - robot.lower
    return robot.lower + span * (margin + (1 - 2 * margin) * rng.random((count, robot.n)))


def random_velocities(robot, count, seed):
    return np.random.default_rng(seed).normal(size=(count, robot.n))
