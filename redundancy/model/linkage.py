"""`LinkageCylinder`: a cylinder driving a revolute joint through a planar four-bar linkage.

The excavator's bucket: the driven joint (the bucket joint) joins the carrying link (the stick)
to the driven link (the bucket). A rocker pivots on the stick at R and ends at the pin P; a
coupler joins P to the pin C on the bucket; the cylinder runs from its base point b on the stick
to P, where rocker, coupler and rod share one pin, as on most excavator buckets. Rocker and
coupler are not links of the URDF: the chain stays serial, and the loop is closed here.

Loop closure, solved in closed form by the compiled core (`redundancy._core`, which the
methods below call): P lies in the linkage's plane through R, normal to the
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
from redundancy.model.actuators import CompiledMap, actuate, prismatic
from redundancy.model.kinematics import WORLD, Kinematics
from redundancy.model.parameters import Arm, Number, Point

OPEN_LOOP = 2  # the core's status where a loop cannot close


class LinkageCylinder(CompiledMap):
    """A cylinder from ``base`` (a point on a link) to the pin joining a rocker and a coupler.

    ``rocker`` = (link, pivot R (3,) m in the link frame, length r m); ``coupler`` = (link,
    pin C (3,) m in the frame of the driven link, length c m); ``branch`` ±1 the assembly
    branch. The math is the module's docstring.
    """

    BRANCHES = (1, -1)
    code = 2
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
        self.frames = [self.attach(model, "base", *self.base)]
        self.frames += [self.attach(model, "pivot", link, pivot)]
        data = model.createData()
        q = pin.neutral(model)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        joint = model.getJointId(self.joint)
        axis = pin.getJointJacobian(model, data, joint, WORLD)[3:, model.joints[joint].idx_v]
        rotation = data.oMf[self.frames[1]].rotation
        axis_point = pivot + rotation.T @ (axis / np.linalg.norm(axis))
        self.frames += [self.attach(model, "axis", link, axis_point)]
        self.frames += [self.attach(model, "pin", *self.coupler[:2])]

    def declare(self, slots):
        return [slots[f] for f in self.frames], [self.rocker[2], self.coupler[2], self.branch]

    def refuse(self, kinematics: Kinematics, state: int, status: int) -> None:
        """A loop that cannot close (the core's status 2) is refused naming the distance of
        pivot and pin in the linkage's plane; anything else as the base refuses it."""
        if status != OPEN_LOOP:
            super().refuse(kinematics, state, status)
        pivot, tip, pin_ = (
            kinematics.positions[state, kinematics.slots[f]] for f in self.frames[1:]
        )
        axis, w = tip - pivot, pin_ - pivot
        apart = np.linalg.norm(w - (axis @ w) * axis)
        r, c, q = self.rocker[2], self.coupler[2], np.round(kinematics.q[state], 6).tolist()
        raise SingularConfigurationError(
            f"linkage {self.name!r} cannot close at q = {q}: "
            f"its rocker ({r:g} m) and coupler ({c:g} m) cannot join pivot "
            f"and pin {apart:.4g} m apart; keep joint {self.joint!r} where they can"
        )

    def ends(self, kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """The cylinder's base point and rod end (the pin P), each (k, 3), world, in m."""
        P = actuate([self], kinematics)[3][:, 0]
        return kinematics.point(self.frames[0]).position, P

    def bars(self, kinematics: Kinematics) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The rocker (R to P) and the coupler (P to C), each as its two ends (k, 3), in m."""
        _, P = self.ends(kinematics)
        pivot, pin_ = (kinematics.point(self.frames[i]).position for i in (1, 3))
        return {"rocker": (pivot, P), "coupler": (P, pin_)}
