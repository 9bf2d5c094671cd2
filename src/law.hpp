// The resolution laws' kernel: the weighted pseudoinverse with its damping near a singular J_H,
// and the null-space term.
#pragma once

#include <algorithm>
#include <cmath>

#include "pass.hpp"

// (G + λ² I)⁻¹ b for one G = J_H W⁻¹ J_Hᵀ (m, m): λ² = 0 where G is provably conditioned,
// det G ≥ ε (tr G)^m (then σ_min / σ_max ≥ ε, and the Cholesky factor gives det G and the
// solve at once); otherwise λ² = ε σ_max (1 − (σ_min / (ε σ_max))²), clamped to [0, ε σ_max].
inline Eigen::VectorXd solve_gram(const Eigen::MatrixXd& G, const Eigen::VectorXd& b,
                                  double ratio) {
  const Eigen::LLT<Eigen::MatrixXd> factor(G);
  if (factor.info() == Eigen::Success) {
    const double root = factor.matrixLLT().diagonal().prod();
    if (root * root >= ratio * std::pow(G.trace(), double(G.rows()))) return factor.solve(b);
  }
  const Eigen::VectorXd eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(G, Eigen::EigenvaluesOnly).eigenvalues();
  const double threshold = ratio * eigenvalues(eigenvalues.size() - 1);
  const double r = std::clamp(eigenvalues(0) / threshold, 0.0, 1.0);
  const Eigen::MatrixXd damped =
      G + threshold * (1 - r * r) * Eigen::MatrixXd::Identity(G.rows(), G.cols());
  return damped.partialPivLu().solve(b);
}

// ẋ = J_W⁺ (ẏ − J_H z) + z, J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹, for one J_H (m, n), ẏ (m), W (n, n)
// or null for I, z (n) or null for 0.
template <class JH>
Eigen::VectorXd law(const JH& J, const Eigen::VectorXd& y_dot, const Eigen::MatrixXd* W,
                    const Eigen::VectorXd* z, double ratio) {
  const Eigen::MatrixXd W_inv_J_T =
      W ? Eigen::MatrixXd(W->partialPivLu().solve(J.transpose())) : Eigen::MatrixXd(J.transpose());
  Eigen::VectorXd target = y_dot;
  if (z) target -= J * *z;
  Eigen::VectorXd x_dot = W_inv_J_T * solve_gram(J * W_inv_J_T, target, ratio);
  if (z) x_dot += *z;
  return x_dot;
}

// The kernel on a batch: J_H (k, m, n), ẏ (k, m), W (k, n, n) or None, z (k, n) or None: ẋ (k, n).
inline Array resolve(const Array& J_H, const Array& y_dot, const std::optional<Array>& W,
                     const std::optional<Array>& z, double ratio) {
  if (J_H.ndim() != 3 || y_dot.ndim() != 2 || y_dot.shape(0) != J_H.shape(0) ||
      y_dot.shape(1) != J_H.shape(1))
    throw py::value_error("resolve takes J_H (k, m, n) and y_dot (k, m)");
  const auto k = J_H.shape(0), m = J_H.shape(1), n = J_H.shape(2);
  if (W && (W->ndim() != 3 || W->shape(0) != k || W->shape(1) != n || W->shape(2) != n))
    throw py::value_error("W must have shape (k, n, n), as J_H (k, m, n)");
  if (z && (z->ndim() != 2 || z->shape(0) != k || z->shape(1) != n))
    throw py::value_error("z must have shape (k, n), as J_H (k, m, n)");
  Array out({k, n});
  Eigen::MatrixXd Wi;
  Eigen::VectorXd zi;
  for (py::ssize_t i = 0; i < k; ++i) {
    if (W) Wi = ConstMatrix(W->data() + i * n * n, n, n);
    if (z) zi = Vector(z->data() + i * n, n);
    Eigen::Map<Eigen::VectorXd>(out.mutable_data() + i * n, n) =
        law(ConstMatrix(J_H.data() + i * m * n, m, n), Vector(y_dot.data() + i * m, m),
            W ? &Wi : nullptr, z ? &zi : nullptr, ratio);
  }
  return out;
}
