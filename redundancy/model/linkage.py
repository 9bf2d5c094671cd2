"""`LinkageCylinder`: a cylinder driving a revolute joint through a planar four-bar linkage.

The excavator's bucket: the driven joint (the bucket joint) joins the carrying link (the stick)
to the driven link (the bucket). A rocker pivots on the stick at R and ends at the pin P; a
coupler joins P to the pin C on the bucket; the cylinder runs from its base point b on the stick
to P, where rocker, coupler and rod share one pin, as on most excavator buckets. Rocker and
coupler are not links of the URDF: the chain stays serial, and the loop is closed here.

Loop closure, solved in closed form: P lies in the linkage's plane through R, normal to the
rocker's pivot axis n (the driven joint's axis), and on the circles |P − R| = r (rocker length)
and |P − C| = c (coupler length). With w = C − R, h = n·w, w' = w − h n (C's projection on the
plane, at d = |w'| from R), c'² = c² − h², e1 = w'/d and e2 = n × e1::

    a = (r² − c'² + d²) / (2 d),   P = R + a e1 + σ √(r² − a²) e2,   x = |P − b|,

σ = ±1 the assembly branch (+1: P on the left of R → C, seen with n towards the viewer). The
loop cannot close where r² < a²; the rocker and coupler fold into one line (a toggle, where
P's Jacobian below is singular) where r² = a².

Derivatives by implicit differentiation of the loop equations g = (½|P − R|², ½|P − C|²,
n·(P − R)) = const: with the rows of M = [(P − R)ᵀ; (P − C)ᵀ; nᵀ] (3, 3),

    M J_P = K,   K = [(P − R)ᵀ J_R; (P − C)ᵀ J_C; nᵀ J_R − (P − R)ᵀ J_n],
    M J̇_P = K̇ − Ṁ J_P,

from the point Jacobians J_R, J_C, J_n = ∂n/∂q of the tracked frames and their rates J̇ (one
Pinocchio pass, `redundancy.model.kinematics`); x and its rows of A and Ȧ then follow as for a
`LinearCylinder` between b and P.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from redundancy.errors import RobotDescriptionError, SingularConfigurationError
from redundancy.model.actuators import VectorisedMap, attach_frame, prismatic, span
from redundancy.model.kinematics import WORLD, Kinematics
from redundancy.model.parameters import Arm, Number, Point


class LinkageCylinder(VectorisedMap):
    """A cylinder from ``base`` (a point on a link) to the pin joining a rocker and a coupler.

    ``rocker`` = (link, pivot R (3,) m in the link frame, length r m); ``coupler`` = (link,
    pin C (3,) m in the frame of the driven link, length c m); ``branch`` ±1 the assembly
    branch. The math is the module's docstring.
    """

    BRANCHES = (1, -1)
    distance = True
    parameters = (
        Point("base", "the cylinder's base point, on the carrying link"),
        Arm("rocker", "the rocker's pivot on the carrying link, and its length to the rod's pin"),
        Arm("coupler", "the coupler's pin on the driven link, and its length to the rod's pin"),
        Number(
            "branch",
            "the assembly branch: the side of the line pivot → pin where rocker and coupler meet",
            allowed=BRANCHES,
        ),
    )

    def __init__(
        self,
        name: str,
        joint: str,
        lower: float,
        upper: float,
        base: tuple[str, np.ndarray | list[float]],
        rocker: tuple[str, np.ndarray | list[float], float],
        coupler: tuple[str, np.ndarray | list[float], float],
        branch: float = 1,
    ):
        super().__init__(name, joint, lower, upper)
        if branch not in self.BRANCHES:
            raise RobotDescriptionError(
                f"linkage {name!r}: branch {branch!r} must be 1 or -1 (the side of the line "
                "from the rocker pivot to the coupler pin where rocker and coupler meet)"
            )
        for part, (_, _, length) in (("rocker", rocker), ("coupler", coupler)):
            if not (np.isfinite(length) and length > 0):
                raise RobotDescriptionError(
                    f"linkage {name!r}: {part} length {length!r} must be a positive number (m)"
                )
        self.base = (base[0], np.asarray(base[1], dtype=float))
        self.rocker = (rocker[0], np.asarray(rocker[1], dtype=float), float(rocker[2]))
        self.coupler = (coupler[0], np.asarray(coupler[1], dtype=float), float(coupler[2]))
        self.branch = int(branch)

    def bind(self, model: pin.Model) -> None:
        """Resolve the links; add frames at the base point, the rocker pivot R, R + n (n the
        driven joint's unit axis, fixed on the rocker's link as at the neutral configuration)
        and the coupler pin C."""
        super().bind(model)
        if prismatic(model, self.joint):
            raise RobotDescriptionError(
                f"linkage {self.name!r}: joint {self.joint!r} is prismatic; a four-bar linkage "
                "drives a revolute joint"
            )
        link, pivot, _ = self.rocker
        self.frames = [attach_frame(model, self.name, "base", *self.base)]
        self.frames.append(attach_frame(model, self.name, "pivot", link, pivot))
        data = model.createData()
        q = pin.neutral(model)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        joint = model.getJointId(self.joint)
        axis = pin.getJointJacobian(model, data, joint, WORLD)[3:, model.joints[joint].idx_v]
        rotation = data.oMf[self.frames[1]].rotation
        axis_point = pivot + rotation.T @ (axis / np.linalg.norm(axis))
        self.frames.append(attach_frame(model, self.name, "axis", link, axis_point))
        self.frames.append(attach_frame(model, self.name, "pin", *self.coupler[:2]))

    @staticmethod
    def _loop(maps, kinematics: Kinematics):
        """Slots of b, R, R + n, C (each (c,)), the points b, R, C, n and P (each (k, c, 3)).

        Raises `SingularConfigurationError` where a loop cannot close."""
        slots = [[kinematics.slots[m.frames[i]] for m in maps] for i in range(4)]
        base, pivot, axis_tip, pin_ = (kinematics.positions.take(s, 1) for s in slots)
        axis = axis_tip - pivot
        r = np.array([m.rocker[2] for m in maps])
        c = np.array([m.coupler[2] for m in maps])
        w = pin_ - pivot
        w_plane = w - (axis * w).sum(2)[..., None] * axis
        d = np.sqrt((w_plane * w_plane).sum(2))
        c_plane2 = c**2 - (axis * w).sum(2) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            a = (r**2 - c_plane2 + d**2) / (2 * d)
            height2 = r**2 - a**2
        open_ = ~(height2 >= 0)  # also NaN where d = 0
        if open_.any():
            state, which = np.argwhere(open_)[0]
            m, q = maps[which], np.round(kinematics.q[state], 6).tolist()
            raise SingularConfigurationError(
                f"linkage {m.name!r} cannot close at q = {q}: "
                f"its rocker ({r[which]:g} m) and coupler ({c[which]:g} m) cannot join pivot "
                f"and pin {d[state, which]:.4g} m apart; keep joint {m.joint!r} where they can"
            )
        e1 = w_plane / d[..., None]
        e2 = np.cross(axis, e1)
        sigma = np.array([m.branch for m in maps])
        P = pivot + a[..., None] * e1 + (sigma * np.sqrt(height2))[..., None] * e2
        return slots, base, pivot, pin_, axis, P

    @staticmethod
    def _pin_jacobian(loop, jacobians):
        """M (k, c, 3, 3), J_P (k, c, 3, n), and J_b, J_R, J_C, J_n of the tracked frames."""
        slots, _, pivot, pin_, axis, P = loop
        J_b, J_R, J_axis, J_C = (jacobians.take(s, 1) for s in slots)
        J_n = J_axis - J_R
        M = np.stack([P - pivot, P - pin_, axis], axis=2)
        K = np.stack(
            [
                ((P - pivot)[..., None] * J_R).sum(2),
                ((P - pin_)[..., None] * J_C).sum(2),
                (axis[..., None] * J_R).sum(2) - ((P - pivot)[..., None] * J_n).sum(2),
            ],
            axis=2,
        )
        return M, np.linalg.solve(M, K), (J_b, J_R, J_C, J_n)

    @classmethod
    def evaluate_group(cls, maps, kinematics):
        loop = cls._loop(maps, kinematics)
        base, P = loop[1], loop[5]
        _, J_P, (J_b, *_) = cls._pin_jacobian(loop, kinematics.jacobians)
        return span(P - base, J_P - J_b, maps)[:2]

    @classmethod
    def rate_group(cls, maps, kinematics):
        loop = cls._loop(maps, kinematics)
        slots, base, pivot, pin_, axis, P = loop
        M, J_P, (J_b, J_R, J_C, J_n) = cls._pin_jacobian(loop, kinematics.jacobians)
        v_b, v_R, v_axis, v_C = (kinematics.velocities.take(s, 1) for s in slots)
        Jd_b, Jd_R, Jd_axis, Jd_C = (kinematics.jacobian_rates.take(s, 1) for s in slots)
        v_n, Jd_n = v_axis - v_R, Jd_axis - Jd_R
        v_P = (J_P @ kinematics.v[:, None, :, None])[..., 0]
        M_dot = np.stack([v_P - v_R, v_P - v_C, v_n], axis=2)

        def row(vector, jacobian):
            """vectorᵀ jacobian, (k, c, n), for vector (k, c, 3) and jacobian (k, c, 3, n)."""
            return (vector[..., None] * jacobian).sum(2)

        K_dot = np.stack(
            [
                row(v_P - v_R, J_R) + row(P - pivot, Jd_R),
                row(v_P - v_C, J_C) + row(P - pin_, Jd_C),
                row(v_n, J_R) + row(axis, Jd_R) - row(v_P - v_R, J_n) - row(P - pivot, Jd_n),
            ],
            axis=2,
        )
        Jd_P = np.linalg.solve(M, K_dot - M_dot @ J_P)
        return span(P - base, J_P - J_b, maps, v_P - v_b, Jd_P - Jd_b)[2]

    def ends(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """The cylinder's base point and rod end (the pin P), each (k, 3), world, in m."""
        _, base, _, _, _, P = self._loop([self], kinematics)
        return base[:, 0], P[:, 0]

    def bars(self, kinematics: Kinematics) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The rocker (R to P) and the coupler (P to C), each as its two ends (k, 3), in m."""
        _, _, pivot, pin_, _, P = self._loop([self], kinematics)
        return {"rocker": (pivot[:, 0], P[:, 0]), "coupler": (P[:, 0], pin_[:, 0])}
