"""The HIAB 031 crane in closed form, typed in from the paper (section 3): the test oracle.

Nothing here is used by the toolkit; the tests compare Pinocchio's model against it. The mass
matrix is Eq. (31) re-derived for the rod model (see paper.md): uniform rods of linear density
rho_i, boom 2 on [0, L2] from joint 2, the telescope on [d3, d3 + L3], a point load at d3 + L3.
"""

from math import pi, radians

import numpy as np

L1, L2, L3 = 1.600, 1.650, 1.470
L11, L12, L21, L22 = 1.037, 0.376, 1.130, 0.310
E, C = 0.228, 0.957
RHO1, RHO2, RHO3 = 80 / L1, 100 / L2, 36 / L3
C1 = -pi / 2 + radians(21.7 + 10.6)  # Eq. (2)
C2 = radians(27.1 + 2.93) - pi  # Eq. (3)
GRAVITY = 9.81


def angles(q):
    """theta1, theta2, d3 from the joint coordinates (Eqs. 2-3)."""
    return q[0] + C1, q[1] + C2, q[2]


def tool(q):
    """Eqs. (4)-(5): (y1, y2)."""
    t1, t2, d3 = angles(q)
    r = L3 + d3
    return np.array(
        [L1 * np.cos(t1) + r * np.cos(t1 + t2) - E, L1 * np.sin(t1) + r * np.sin(t1 + t2) + C]
    )


def actuators(q):
    """Eq. (9): x1, x2, x3."""
    x1 = np.sqrt(L11**2 + L12**2 - 2 * L11 * L12 * np.cos(q[0]))
    x2 = np.sqrt(L21**2 + L22**2 - 2 * L21 * L22 * np.cos(q[1]))
    return np.array([x1, x2, q[2] - L2 + L3])


def torque_arms(q):
    """Eq. (14): the diagonal of A, (a1, a2, 1)."""
    x = actuators(q)
    return np.array([L11 * L12 * np.sin(q[0]) / x[0], L21 * L22 * np.sin(q[1]) / x[1], 1.0])


def mass_matrix(q, load):
    """M(q) in (theta1, theta2, d3), Eq. (31) re-derived; ``load`` is the point load M, kg."""
    _, t2, d3 = angles(q)
    cos2, sin2 = np.cos(t2), np.sin(t2)
    r = d3 + L3
    # Rotational inertia about joint 2 of boom 2, telescope and load (the m22 of Eq. 31).
    b = RHO2 * L2**3 / 3 + RHO3 * (L3 * d3**2 + L3**2 * d3 + L3**3 / 3) + load * r**2
    # The coupling L1 cos(theta2) * (first moment of those bodies about joint 2).
    c = L1 * cos2 * (RHO2 * L2**2 / 2 + RHO3 * (L3 * d3 + L3**2 / 2) + load * r)
    # Their mass moved at L1 by joint 1.
    a = L1**2 * (RHO2 * L2 + RHO3 * L3 + load)
    m11 = RHO1 * L1**3 / 3 + a + b + 2 * c
    m12 = b + c
    m13 = (L1 * L3 * RHO3 + L1 * load) * sin2
    m33 = L3 * RHO3 + load
    return np.array([[m11, m12, m13], [m12, b, 0.0], [m13, 0.0, m33]])


def mass_matrix_hydraulic(q, load):
    """Eq. (30): M_H = A^-1 M A^-1 with A = diag(a1, a2, 1)."""
    inverse = 1 / torque_arms(q)
    return mass_matrix(q, load) * np.outer(inverse, inverse)


def gravity(q, load):
    """G = dU/dq with U the potential energy of rods and load under gravity along -y2."""
    t1, t2, d3 = angles(q)
    c1, c12, s12 = np.cos(t1), np.cos(t1 + t2), np.sin(t1 + t2)
    m1, m2, m3 = RHO1 * L1, RHO2 * L2, RHO3 * L3
    # Moment of boom 2, telescope and load about joint 2, along boom 2.
    moment2 = m2 * L2 / 2 + m3 * (d3 + L3 / 2) + load * (d3 + L3)
    g1 = (m1 * L1 / 2 + (m2 + m3 + load) * L1) * c1 + moment2 * c12
    g2 = moment2 * c12
    g3 = (m3 + load) * s12
    return GRAVITY * np.array([g1, g2, g3])
