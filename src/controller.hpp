// One control step in one call: the pass at q, the task point y and J, the actuators' x and A,
// J_H = J A⁻¹, the law's W and z, the kernel, q̇ = A⁻¹ ẋ.
#pragma once

#include <optional>
#include <vector>

#include "rule.hpp"

class Controller {
 public:
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
        actuation_{tool, std::move(rows), declared(kinds, slots, numbers, pass.size(), pass.n())},
        rule_(pass.n(), weight, W, pull, middle, ratio),
        tolerance_(tolerance),
        fallback_(std::move(fallback)),
        result_(std::move(result)) {
    const auto n = pass_.n();
    const auto& task = actuation_.rows;
    if (tool < 0 || tool >= pass_.size() || Eigen::Index(actuation_.actuators.size()) != n ||
        std::any_of(task.begin(), task.end(), [](auto r) { return r < 0 || r > 2; }))
      throw py::value_error("a controller takes the tool's slot, its task rows and n actuators");
    if (!PyType_Check(result_.ptr()) ||
        !PyType_IsSubtype(reinterpret_cast<PyTypeObject*>(result_.ptr()), &PyTuple_Type))
      throw py::value_error("a controller's result is a tuple type (x_dot, q_dot, y)");
    A_.resize(n, n);
    J_.resize(Eigen::Index(task.size()), n);
    J_H_.resize(Eigen::Index(task.size()), n);
    x_.resize(n);
    y_.resize(Eigen::Index(task.size()));
  }

  py::object step(const py::object& q, const py::object& y_dot) {
    const auto n = pass_.n(), m = Eigen::Index(actuation_.rows.size());
    const double *qi = finite(q, n), *yi = finite(y_dot, m);
    if (!qi || !yi) return fallback_(q, y_dot);
    pass_.at(qi, nullptr);
    if (actuation_(pass_.frames(), qi, nullptr, x_.data(), A_.data(), y_.data(), J_.data())
            .second != OK)
      return fallback_(q, y_dot);
    if (derive_state(factors_, A_, J_, J_H_, tolerance_)) return fallback_(q, y_dot);
    const auto* x_dot = rule_(pass_, qi, x_, factors_, J_H_, Vector(yi, m));
    if (!x_dot) return fallback_(q, y_dot);
    factors_.solve(*x_dot, q_dot_);  // q̇ = A⁻¹ ẋ
    return result(vector(*x_dot), vector(q_dot_), vector(y_));
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
  Actuation actuation_;
  Rule rule_;
  Matrix A_, J_;  // row-major, as `Actuation` writes them
  Dense J_H_;
  Factors factors_;
  Eigen::VectorXd x_, y_, q_dot_;
  double tolerance_;
  py::object fallback_, result_;
};
