"""Joint-space quantities of a robot at configurations of shape (n,) or (k, n), answered in the
same form, for the tests to check the toolkit against: the task point and its Jacobian from the
one pass, and Pinocchio's M (CRBA), G and RNEA."""

import numpy as np
import pinocchio as pin


def _each(robot, function, *arrays):
    """``function`` (q, ...) → (…) over the rows of ``arrays`` (n,) or (k, n), as they came."""
    batches = [np.atleast_2d(np.asarray(a, dtype=float)) for a in arrays]
    out = np.array([function(*rows) for rows in zip(*batches)])
    return out[0] if np.ndim(arrays[0]) == 1 else out


def fk(robot, q):
    """Task coordinates y = h1(q) (Eq. 6), (m,) or (k, m), in m."""
    return _each(robot, lambda qi: robot.task(robot.kinematics(qi[None])).position[0], q)


def jacobian(robot, q):
    """Task Jacobian J = ∂y/∂q (Eq. 7), (m, n) or (k, m, n)."""
    return _each(robot, lambda qi: robot.task(robot.kinematics(qi[None])).jacobian[0], q)


def mass(robot, q):
    """Joint-space inertia M(q) (Eq. 18), (n, n) or (k, n, n)."""
    return _each(robot, lambda qi: robot.mass_matrices(qi[None])[0], q)


def gravity(robot, q):
    """Gravity torques G(q) (Eq. 18), (n,) or (k, n)."""
    data = robot.model.createData()
    return _each(robot, lambda qi: pin.computeGeneralizedGravity(robot.model, data, qi), q)


def inverse_dynamics(robot, q, v, a):
    """τ = M(q) a + V(q, v) + G(q) (Eq. 18) by RNEA, (n,) or (k, n)."""
    data = robot.model.createData()
    return _each(robot, lambda *s: pin.rnea(robot.model, data, *s), q, v, a)


def mechanical_energy(robot, q, v):
    """T + V (k,), J, at the states q, v (k, n): T = ½ q̇ᵀ M q̇ with Pinocchio's CRBA and
    V = −m g·c with its centre of mass c (Pinocchio's own energy functions refuse mimic
    joints)."""
    model, data = robot.model, robot.model.createData()
    weight = pin.computeTotalMass(model) * model.gravity.linear

    def energy(qi, vi):
        upper = np.triu(pin.crba(model, data, qi))  # the CRBA fills the upper triangle
        return vi @ (upper + np.triu(upper, 1).T) @ vi / 2 - weight @ pin.centerOfMass(
            model, data, qi
        )

    return np.array([energy(qi, vi) for qi, vi in zip(q, v)])
