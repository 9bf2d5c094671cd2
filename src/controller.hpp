// One control step in one call: the pass at q, the task point y and J, the actuators' x and A,
// J_H = J A⁻¹, the law's W and z, the kernel, q̇ = A⁻¹ ẋ.
#pragma once

#include <optional>
#include <vector>

#include "actuators.hpp"
#include "law.hpp"

class Controller {
 public:
  // How the law weighs ẋ: W = I, W = M_H, or a constant W given once.
  enum Weight : int { IDENTITY = 0, INERTIA = 1, CONSTANT = 2 };

  // `pass` tracks the tool (slot `tool`, task rows `rows` of its position) and the actuators'
  // frames; the law is its `weight` (with `W` for CONSTANT) and, where `pull` (n) is given, the
  // null-space term z = pull ∘ (x − middle). `fallback(q, y_dot)` is the Python step: it answers
  // whatever this one does not (input that is not one finite float vector each, a singular A, a
  // kind that cannot evaluate, a mass matrix without mass), raising the toolkit's errors there.
  Controller(const Pass& pass, Eigen::Index tool, std::vector<Eigen::Index> rows,
             const py::array_t<int>& kinds, const py::array_t<Eigen::Index>& slots,
             const Array& numbers, int weight, const std::optional<Array>& W,
             const std::optional<Array>& pull, const std::optional<Array>& middle, double ratio,
             double tolerance, py::object fallback, py::object result)
      : pass_(pass),
        tool_(tool),
        rows_(std::move(rows)),
        actuators_(declared(kinds, slots, numbers, pass.size(), pass.n())),
        weight_(Weight(weight)),
        ratio_(ratio),
        tolerance_(tolerance),
        fallback_(std::move(fallback)),
        result_(std::move(result)) {
    const auto n = pass_.n();
    if (tool_ < 0 || tool_ >= pass_.size() || Eigen::Index(actuators_.size()) != n ||
        std::any_of(rows_.begin(), rows_.end(), [](auto r) { return r < 0 || r > 2; }))
      throw py::value_error("a controller takes the tool's slot, its task rows and n actuators");
    if (weight_ == CONSTANT) {
      if (!W || W->ndim() != 2 || W->shape(0) != n || W->shape(1) != n)
        throw py::value_error("a constant weight W must have shape (n, n)");
      W_ = ConstMatrix(W->data(), n, n);
    }
    if (pull.has_value() != middle.has_value() ||
        (pull && (pull->size() != n || middle->size() != n)))
      throw py::value_error("the null-space pull and its middle must both be (n,)");
    if (pull) {
      pull_ = Vector(pull->data(), n);
      middle_ = Vector(middle->data(), n);
    }
    if (!PyType_Check(result_.ptr()) ||
        !PyType_IsSubtype(reinterpret_cast<PyTypeObject*>(result_.ptr()), &PyTuple_Type))
      throw py::value_error("a controller's result is a tuple type (x_dot, q_dot, y)");
    A_.resize(n, n);
    J_.resize(Eigen::Index(rows_.size()), n);
  }

  py::object step(const py::object& q, const py::object& y_dot) {
    const auto n = pass_.n(), m = Eigen::Index(rows_.size());
    const double *qi = finite(q, n), *yi = finite(y_dot, m);
    if (!qi || !yi) return fallback_(q, y_dot);
    pass_.at(qi, nullptr);
    const Frames s = pass_.frames();
    Eigen::VectorXd x(n), y(m);
    Eigen::Vector3d end;
    for (Eigen::Index j = 0; j < n; ++j)
      if (actuate(actuators_[j], s, qi, nullptr, x[j], RowOut(A_.row(j).data(), n), nullptr,
                  end) != OK)
        return fallback_(q, y_dot);
    for (Eigen::Index r = 0; r < m; ++r) {
      y[r] = s.position(tool_)[rows_[r]];
      J_.row(r) = s.jacobian(tool_).row(rows_[r]);
    }
    if (singular()) return fallback_(q, y_dot);
    const auto transposed = A_.transpose().partialPivLu();
    const Eigen::MatrixXd J_H = transposed.solve(J_.transpose()).transpose();
    const Eigen::MatrixXd* W = weight_ == CONSTANT ? &W_ : nullptr;
    if (weight_ == INERTIA) {
      const Eigen::MatrixXd& M = pass_.mass(qi);
      if (!(M.diagonal().array() > 0).all()) return fallback_(q, y_dot);
      const Eigen::MatrixXd half = transposed.solve(transposed.solve(M).transpose());
      M_H_ = (half + half.transpose()) / 2;
      W = &M_H_;
    }
    std::optional<Eigen::VectorXd> z;
    if (pull_.size()) z = pull_.cwiseProduct(x - middle_);
    const Eigen::VectorXd x_dot = law(J_H, Eigen::VectorXd(Vector(yi, m)), W, z ? &*z : nullptr,
                                      ratio_);
    const Eigen::VectorXd q_dot = A_.partialPivLu().solve(x_dot);
    return result(vector(x_dot), vector(q_dot), vector(y));
  }

 private:
  // The data of a one-dimensional, contiguous float64 array of `size` finite values, or null.
  static const double* finite(const py::object& value, Eigen::Index size) {
    if (!py::isinstance<py::array_t<double>>(value)) return nullptr;
    const auto array = py::reinterpret_borrow<py::array>(value);
    if (array.ndim() != 1 || array.shape(0) != size || array.strides(0) != py::ssize_t(sizeof(double)))
      return nullptr;
    const auto* data = static_cast<const double*>(array.data());
    return Vector(data, size).allFinite() ? data : nullptr;
  }

  // Whether A is singular to working precision, as `redundancy.resolution.state.singular`:
  // |det A| / ‖A‖_F^n bounds σ_min / σ_max from below; below the tolerance, the singular values.
  bool singular() const {
    if (!A_.allFinite()) return true;
    const double n = double(A_.rows());
    if (std::abs(A_.determinant()) > tolerance_ * std::pow(A_.squaredNorm(), n / 2)) return false;
    const Eigen::VectorXd sigma = Eigen::JacobiSVD<Eigen::MatrixXd>(A_).singularValues();
    return sigma[sigma.size() - 1] / std::max(sigma[0], std::numeric_limits<double>::min()) <
           tolerance_;
  }

  // The result type's tuple of the three, filled as tuple's own constructor fills a subtype's
  // (the type adds no field), without a call into Python.
  py::object result(Array x_dot, Array q_dot, Array y) const {
    auto* type = reinterpret_cast<PyTypeObject*>(result_.ptr());
    PyObject* out = type->tp_alloc(type, 3);
    if (!out) throw py::error_already_set();
    PyTuple_SET_ITEM(out, 0, x_dot.release().ptr());
    PyTuple_SET_ITEM(out, 1, q_dot.release().ptr());
    PyTuple_SET_ITEM(out, 2, y.release().ptr());
    return py::reinterpret_steal<py::object>(out);
  }

  static Array vector(const Eigen::VectorXd& values) {
    Array out(values.size());
    Eigen::Map<Eigen::VectorXd>(out.mutable_data(), values.size()) = values;
    return out;
  }

  Pass pass_;
  Eigen::Index tool_;
  std::vector<Eigen::Index> rows_;
  std::vector<Actuator> actuators_;
  Weight weight_;
  Eigen::MatrixXd W_, M_H_, J_;
  Matrix A_;  // row-major: each actuator writes its row in place
  Eigen::VectorXd pull_, middle_;
  double ratio_, tolerance_;
  py::object fallback_, result_;
};
