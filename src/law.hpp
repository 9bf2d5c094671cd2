// The resolution laws' kernel: the weighted pseudoinverse with its damping near a singular J_H,
// and the null-space term.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "space.hpp"

// The weighted pseudoinverse for one state at a time, its products kept from state to state (an
// undamped state of an unweighted law allocates nothing once they are sized):
//   ẋ = J_W⁺ (ẏ − J_H z) + z,   J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹,
// for J_H (m, n), ẏ (m), W (n, n) or null for I, z (n) or null for 0. It is computed without
// W⁻¹, so that a weight near singular (a link of almost no mass in M_H) neither loses the task
// nor passes for a singularity of J_H: first the least-norm solution d₀ = J_Hᵀ G⁻¹ (ẏ − J_H z)
// with G = J_H J_Hᵀ (m, m), then, for a weight, the step along the null space of J_H that makes
// d = d₀ + N u least in dᵀ W d: Nᵀ W d = 0, that is u = −(Nᵀ W N)⁻¹ Nᵀ W d₀, with N (n, n − m)
// an orthonormal basis of that null space (the last columns of the Householder Q of J_Hᵀ). Then
// W d lies in the range of J_Hᵀ and J_H d = J_H d₀: d = J_W⁺ J_H d₀, the formula above wherever
// it is defined. G is solved undamped where it is provably conditioned, det G ≥ ε (tr G)^m (then
// σ_min / σ_max ≥ ε, and the Cholesky factor gives det G and the solve at once); otherwise with
// λ² = ε σ_max (1 − (σ_min / (ε σ_max))²), clamped to [0, ε σ_max], added to its diagonal.
class Law {
 public:
  template <class JH, class Velocity>
  const Eigen::VectorXd& operator()(const JH& J, const Velocity& y_dot, const Dense* W,
                                    const Eigen::VectorXd* z, double ratio) {
    target_ = y_dot;
    if (z) target_.noalias() -= J * *z;
    G_.noalias() = J * J.transpose();
    x_dot_.noalias() = J.transpose() * gram(ratio);
    if (W && J.cols() > J.rows()) weigh(J, *W);
    if (z) x_dot_ += *z;
    return x_dot_;
  }

  // Whether the last state's G was damped, λ² > 0: J_H singular to the law's ratio.
  bool damped() const { return damped_; }

 private:
  // d₀ (in x_dot_) moved along the null space of J_H to d = d₀ + N u, Nᵀ W d = 0.
  template <class JH>
  void weigh(const JH& J, const Dense& W) {
    const auto n = J.cols(), r = n - J.rows();
    qr_.compute(J.transpose());
    N_.setZero(n, r);
    N_.bottomRows(r).setIdentity();
    N_.applyOnTheLeft(qr_.householderQ());  // Q's last r columns, without forming Q
    W_N_.noalias() = W * N_;
    reduced_.noalias() = N_.transpose() * W_N_;
    W_d_.noalias() = W * x_dot_;
    u_.noalias() = N_.transpose() * W_d_;
    if (r == 1) {
      u_(0) /= reduced_(0, 0);
    } else {
      factor_.compute(reduced_);
      u_ = factor_.solve(u_);
    }
    x_dot_.noalias() -= N_ * u_;
  }

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
        damped_ = false;
        lambda_ = target_;
        cholesky.solveInPlace(lambda_);  // a solve's expression would copy at m = 1
        return lambda_;
      }
    }
    const Eigen::VectorXd eigenvalues =
        Eigen::SelfAdjointEigenSolver<Dense>(G_, Eigen::EigenvaluesOnly).eigenvalues();
    const double threshold = ratio * eigenvalues(eigenvalues.size() - 1);
    const double r = std::clamp(eigenvalues(0) / threshold, 0.0, 1.0);
    damped_ = r < 1;  // λ² > 0: the determinant's test is sufficient only, at m ≥ 3
    G_.diagonal().array() += threshold * (1 - r * r);
    lambda_ = G_.partialPivLu().solve(target_);
    return lambda_;
  }

  Eigen::HouseholderQR<Dense> qr_;
  Dense G_, N_, W_N_, reduced_;
  Factor factor_;
  Eigen::LLT<Dense> cholesky_;
  Eigen::VectorXd target_, lambda_, x_dot_, W_d_, u_;
  bool damped_ = false;
};

// A law that moves the held actuators `rows` (h) at rates of its own and the others so as to
// resolve the task (`redundancy.resolution.laws.HeldRates`): the ẋ (n) solving
//   [J_H; E_h] ẋ = [ẏ; ẋ_h]
// for J_H (m, n), ẏ (m) and the held rates ẋ_h (n − m), E_h the rows of I that pick the held
// actuators; null where that matrix is singular (a pivot of its LU factors exactly zero).
class Held {
 public:
  Held(std::vector<Eigen::Index> rows, Eigen::Index n) : rows_(std::move(rows)) {
    if (std::any_of(rows_.begin(), rows_.end(), [n](auto r) { return r < 0 || r >= n; }))
      throw py::value_error("the held actuators' rows must be among the n actuators");
  }

  template <class JH, class Velocity, class Rates>
  const Eigen::VectorXd* operator()(const JH& J, const Velocity& y_dot, const Rates& held) {
    const auto m = J.rows(), n = J.cols(), h = Eigen::Index(rows_.size());
    if (m + h != n || held.size() != h)
      throw py::value_error("a held law holds n − m actuators, one rate each");
    K_.setZero(n, n);
    K_.topRows(m) = J;
    target_.resize(n);
    target_.head(m) = y_dot;
    target_.tail(h) = held;
    for (Eigen::Index i = 0; i < h; ++i) K_(m + i, rows_[std::size_t(i)]) = 1;
    factor_.compute(K_);
    if (zero_pivot(factor_)) return nullptr;
    x_dot_ = factor_.solve(target_);
    return &x_dot_;
  }

  const std::vector<Eigen::Index>& rows() const { return rows_; }

 private:
  std::vector<Eigen::Index> rows_;
  Dense K_;
  Factor factor_;
  Eigen::VectorXd target_, x_dot_;
};

// The held law on a batch: J_H (k, m, n), ẏ (k, m), the held rows (h) and their rates (k, h):
// ẋ (k, n); numpy's LinAlgError where [J_H; E_h] is singular, as `solve` raises it.
inline Array held(const Array& J_H, const Array& y_dot, std::vector<Eigen::Index> rows,
                  const Array& rates) {
  if (J_H.ndim() != 3 || y_dot.ndim() != 2 || rates.ndim() != 2 || y_dot.shape(0) != J_H.shape(0) ||
      y_dot.shape(1) != J_H.shape(1) || rates.shape(0) != J_H.shape(0))
    throw py::value_error("held takes J_H (k, m, n), y_dot (k, m) and the held rates (k, h)");
  const auto k = J_H.shape(0), m = J_H.shape(1), n = J_H.shape(2), h = rates.shape(1);
  Held law(std::move(rows), n);
  Array out({k, n});
  for (py::ssize_t i = 0; i < k; ++i) {
    const auto* x_dot = law(at(J_H, i, m, n), at(y_dot, i, 1, m).transpose(),
                            at(rates, i, 1, h).transpose());
    if (!x_dot) singular_matrix();
    at(out, i, 1, n) = x_dot->transpose();
  }
  return out;
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
  fraction(ratio, "the law's singular ratio");
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
