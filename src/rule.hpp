// A built-in law as the kernel runs it (`redundancy.resolution.laws`): its weight W (I, M_H or a
// constant) and its null-space term z = pull ∘ (x − middle), or none.
#pragma once

#include <optional>

#include "law.hpp"
#include "space.hpp"

struct Rule {
  enum Weight : int { IDENTITY = 0, INERTIA = 1, CONSTANT = 2 };

  Rule(Eigen::Index n, int weight, const std::optional<Array>& W,
       const std::optional<Array>& pull, const std::optional<Array>& middle, double ratio)
      : weight(Weight(weight)), ratio(fraction(ratio, "the law's singular ratio")) {
    if (weight < IDENTITY || weight > CONSTANT)
      throw py::value_error("a law's weight is 0 (I), 1 (M_H) or 2 (a constant W)");
    if (this->weight == CONSTANT) {
      if (!W || W->ndim() != 2 || W->shape(0) != n || W->shape(1) != n)
        throw py::value_error("a constant weight W must have shape (n, n)");
      this->W = ConstMatrix(W->data(), n, n);
    }
    if (pull.has_value() != middle.has_value() ||
        (pull && (pull->size() != n || middle->size() != n)))
      throw py::value_error("the null-space pull and its middle must both be (n,)");
    if (pull) {
      this->pull = Vector(pull->data(), n);
      this->middle = Vector(middle->data(), n);
    }
  }

  // ẋ at one state of `pass`: q (n), x (n), the factors of Aᵀ, J_H (m, n) and ẏ (m); null
  // where the law weighs by M_H and M(q) has no positive diagonal (a robot without masses).
  template <class Strokes, class Jacobian, class Velocity>
  const Eigen::VectorXd* operator()(Pass& pass, const double* q, const Strokes& x,
                                    Factors& factors, const Jacobian& J_H,
                                    const Velocity& y_dot) {
    const Dense* weighting = weight == CONSTANT ? &W : nullptr;
    if (weight == INERTIA) {
      const Dense& M = pass.mass(q);
      if (!(M.diagonal().array() > 0).all()) return nullptr;
      inertia(factors, M, first_, second_, M_H);
      weighting = &M_H;
    }
    if (pull.size()) z_ = pull.cwiseProduct(x - middle);
    return &law_(J_H, y_dot, weighting, pull.size() ? &z_ : nullptr, ratio);
  }

  // Whether the last state's J_H was singular to the ratio (its G damped).
  bool damped() const { return law_.damped(); }

  Weight weight;
  Dense W, M_H;
  Eigen::VectorXd pull, middle;
  double ratio;

 private:
  Law law_;
  Dense first_, second_;
  Eigen::VectorXd z_;
};
