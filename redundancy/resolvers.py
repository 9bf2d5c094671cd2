"""Instantaneous redundancy resolution laws in actuator coordinates: ẋ = resolve(state, ẏ).

Every law returns a solution of J_H ẋ = ẏ (Eq. 16) for a batch of states. The weighted
pseudoinverse minimising ẋᵀ W ẋ is (Eq. 27)

    J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹

with W = I for the minimum actuator-velocity norm (Eqs. 24, 26) and W = M_H for the minimum
kinetic energy (Eqs. 29, 32).

Near a singularity of J_H (the task Jacobian losing rank), the m×m matrix G = J_H W⁻¹ J_Hᵀ is
damped: λ² I is added to it, λ² = ε σ_max (1 − (σ_min / (ε σ_max))²), when the ratio of its
smallest to its largest eigenvalue falls below ε (Nakamura and Hanafusa's variable damping,
made scale-free). ẋ then stays finite and bounded, and J_H ẋ departs from ẏ by an amount the
simulation reports as tracking error; away from singularities the laws are exact.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from redundancy.actuator_space import ActuatorSpace

# The gradient-projection gain α, m²/s, tuned on the paper's segments by
# `redundancy.peers.tune_gradient_projection`: the least worst-case peak ẋᵀẋ among the gains
# that keep every stroke inside its limits from the default starts (see benchmarks/results.md).
TUNED_GAIN = 0.07
SINGULAR_RATIO = 1e-8  # ε: G counts as near singular below σ_min / σ_max = ε (cond J_H ≈ 1e4)


def weighted_pseudoinverse(J_H: np.ndarray, W_inv_J_T: np.ndarray) -> np.ndarray:
    """J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ + λ² I)⁻¹ (Eq. 27), (k, n, m), given W⁻¹ J_Hᵀ (k, n, m).

    λ² is zero unless J_H W⁻¹ J_Hᵀ is near singular (see the module docstring).
    """
    gram = J_H @ W_inv_J_T
    m = gram.shape[1]
    # det G / (tr G)^m is at most σ_min / σ_max: where it reaches ε, λ² = 0 without eigenvalues
    if not np.all(np.linalg.det(gram) >= SINGULAR_RATIO * np.einsum("kii->k", gram) ** m):
        eigenvalues = np.linalg.eigvalsh(gram)
        threshold = SINGULAR_RATIO * eigenvalues[:, -1]
        ratio = np.minimum(np.maximum(eigenvalues[:, 0] / threshold, 0.0), 1.0)
        damping = threshold * (1 - ratio**2)
        gram = gram + damping[:, None, None] * np.eye(m)
    return np.swapaxes(np.linalg.solve(gram, np.swapaxes(W_inv_J_T, 1, 2)), 1, 2)


class Resolver(ABC):
    """An instantaneous resolution law ẋ = f(state, ẏ)."""

    name: str = "resolver"

    @abstractmethod
    def resolve(self, space: ActuatorSpace, y_dot: np.ndarray) -> np.ndarray:
        """Actuator velocities ẋ (k, n) for task velocities ẏ (k, m) at the states of ``space``."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class MinVelocityNorm(Resolver):
    """ẋ = J_H⁺ ẏ (Eq. 24): among all ẋ with J_H ẋ = ẏ, the one of least ẋᵀẋ."""

    name = "unweighted pseudoinverse (min ẋᵀẋ)"

    def pseudoinverse(self, space: ActuatorSpace) -> np.ndarray:
        """J_H⁺ = J_Hᵀ (J_H J_Hᵀ)⁻¹ (Eq. 26), (k, n, m)."""
        return weighted_pseudoinverse(space.J_H, np.swapaxes(space.J_H, 1, 2))

    def resolve(self, space: ActuatorSpace, y_dot: np.ndarray) -> np.ndarray:
        return (self.pseudoinverse(space) @ y_dot[..., None])[..., 0]


class MinKineticEnergy(Resolver):
    """ẋ = J_MH⁺ ẏ (Eqs. 29, 32): among all ẋ with J_H ẋ = ẏ, the one of least ẋᵀ M_H ẋ."""

    name = "M_H-weighted pseudoinverse (min ẋᵀ M_H ẋ)"

    def resolve(self, space: ActuatorSpace, y_dot: np.ndarray) -> np.ndarray:
        W_inv_J_T = np.linalg.solve(space.M_H, np.swapaxes(space.J_H, 1, 2))
        return (weighted_pseudoinverse(space.J_H, W_inv_J_T) @ y_dot[..., None])[..., 0]


class GradientProjection(MinVelocityNorm):
    """ẋ = J_H⁺ ẏ + (I − J_H⁺ J_H) z, z = α ∇Φ(x) (Eq. 1 in actuator coordinates).

    Φ(x) = −½ Σ_i ((x_i − x̄_i) / (x_i,max − x_i,min))² rewards strokes near mid-range x̄
    (Liégeois' joint-limit avoidance, on actuators), so z_i = −α (x_i − x̄_i) / Δx_i², in m/s for
    the gain α in m²/s. Actuators with infinite strokes are not pushed.
    The null-space term leaves J_H ẋ = ẏ unchanged. This is the baseline the paper argues
    against.
    """

    name = "gradient projection (limit avoidance)"

    def __init__(self, gain: float = TUNED_GAIN):
        self.gain = gain

    def __repr__(self) -> str:
        return f"GradientProjection(gain={self.gain})"

    def resolve(self, space: ActuatorSpace, y_dot: np.ndarray) -> np.ndarray:
        actuators = space.robot.actuators
        span = actuators.upper - actuators.lower
        finite = np.isfinite(span)
        middle = np.where(finite, (actuators.upper + actuators.lower) / 2, 0.0)
        scale = np.where(finite, 1 / np.where(finite, span, 1.0) ** 2, 0.0)
        z = -self.gain * (space.x - middle) * scale
        pinv = self.pseudoinverse(space)
        projector = np.eye(space.x.shape[1]) - pinv @ space.J_H
        return (pinv @ y_dot[..., None] + projector @ z[..., None])[..., 0]
