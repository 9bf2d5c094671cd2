// The resolution laws' kernel: the weighted pseudoinverse with its damping near a singular J_H,
// and the null-space term.
#pragma once

#include <algorithm>
#include <cmath>

#include "space.hpp"

// The weighted pseudoinverse for one state at a time, its products kept from state to state (an
// undamped state allocates nothing once they are sized):
//   ẋ = J_W⁺ (ẏ − J_H z) + z,   J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹,
// for J_H (m, n), ẏ (m), W (n, n) or null for I, z (n) or null for 0. The Gram matrix
// G = J_H W⁻¹ J_Hᵀ (m, m) is solved undamped where it is provably conditioned, det G ≥ ε (tr G)^m
// (then σ_min / σ_max ≥ ε, and the Cholesky factor gives det G and the solve at once); otherwise
// with λ² = ε σ_max (1 − (σ_min / (ε σ_max))²), clamped to [0, ε σ_max], added to its diagonal.
class Law {
 public:
  template <class JH, class Velocity>
  const Eigen::VectorXd& operator()(const JH& J, const Velocity& y_dot, const Dense* W,
                                    const Eigen::VectorXd* z, double ratio) {
    if (W) {
      weight_.compute(*W);
      W_inv_J_T_ = weight_.solve(J.transpose());
    } else {
      W_inv_J_T_ = J.transpose();
    }
    target_ = y_dot;
    if (z) target_.noalias() -= J * *z;
    G_.noalias() = J * W_inv_J_T_;
    x_dot_.noalias() = W_inv_J_T_ * gram(ratio);
    if (z) x_dot_ += *z;
    return x_dot_;
  }

 private:
  // (G + λ² I)⁻¹ (ẏ − J_H z), through Eigen's fixed-size Cholesky kernels for a task of up to
  // three coordinates (at m = 2 the dynamic ones spend most of their time deciding sizes), its
  // dynamic ones, kept from state to state, beyond.
  const Eigen::VectorXd& gram(double ratio) {
    switch (G_.rows()) {
      case 1: return gram(Eigen::LLT<Eigen::Matrix<double, 1, 1>>(), ratio);
      case 2: return gram(Eigen::LLT<Eigen::Matrix2d>(), ratio);
      case 3: return gram(Eigen::LLT<Eigen::Matrix3d>(), ratio);
      default: return gram(cholesky_, ratio);
    }
  }

  template <class Cholesky>
  const Eigen::VectorXd& gram(Cholesky&& cholesky, double ratio) {
    cholesky.compute(G_);
    if (cholesky.info() == Eigen::Success) {
      const double root = cholesky.matrixLLT().diagonal().prod();
      if (root * root >= ratio * std::pow(G_.trace(), double(G_.rows()))) {
        lambda_ = target_;
        cholesky.solveInPlace(lambda_);  // a solve's expression would copy at m = 1
        return lambda_;
      }
    }
    const Eigen::VectorXd eigenvalues =
        Eigen::SelfAdjointEigenSolver<Dense>(G_, Eigen::EigenvaluesOnly).eigenvalues();
    const double threshold = ratio * eigenvalues(eigenvalues.size() - 1);
    const double r = std::clamp(eigenvalues(0) / threshold, 0.0, 1.0);
    G_.diagonal().array() += threshold * (1 - r * r);
    lambda_ = G_.partialPivLu().solve(target_);
    return lambda_;
  }

  Factor weight_;
  Dense W_inv_J_T_, G_;
  Eigen::LLT<Dense> cholesky_;
  Eigen::VectorXd target_, lambda_, x_dot_;
};

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
  Dense Wi;
  Eigen::VectorXd zi;
  Law law;
  for (py::ssize_t i = 0; i < k; ++i) {
    if (W) Wi = ConstMatrix(W->data() + i * n * n, n, n);
    if (z) zi = Vector(z->data() + i * n, n);
    Eigen::Map<Eigen::VectorXd>(out.mutable_data() + i * n, n) =
        law(ConstMatrix(J_H.data() + i * m * n, m, n), Vector(y_dot.data() + i * m, m),
            W ? &Wi : nullptr, z ? &zi : nullptr, ratio);
  }
  return out;
}
