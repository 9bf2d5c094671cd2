// One control step in one call: the pass at q, the task point y and J, the actuators' x and A,
// J_H = J A⁻¹, the law's W and z, the kernel, q̇ = A⁻¹ ẋ; and the state a step reads, with M_H,
// in one call.
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
  // kind that cannot evaluate, a step not finite, a mass matrix without mass or not finite),
  // raising the toolkit's errors there;
  // `state_fallback(q)` is the Python state likewise. `result` and `state` are the tuple types
  // of a step (x_dot, q_dot, y) and of a state (x, A, J_H, M_H); with `masses` false (a robot
  // without masses) a state's M_H is None.
  Controller(const Pass& pass, Eigen::Index tool, std::vector<Eigen::Index> rows,
             const py::array_t<int>& kinds, const py::array_t<Eigen::Index>& slots,
             const Array& numbers, int weight, const std::optional<Array>& W,
             const std::optional<Array>& pull, const std::optional<Array>& middle, double ratio,
             double tolerance, py::object fallback, py::object result, py::object state_fallback,
             py::object state, bool masses)
      : evaluator_(pass, tool, std::move(rows), kinds, slots, numbers, tolerance),
        rule_(pass.n(), weight, W, pull, middle, ratio),
        masses_(masses),
        fallback_(std::move(fallback)),
        state_fallback_(std::move(state_fallback)),
        result_(std::move(result)),
        state_(std::move(state)) {
    for (const auto* type : {&result_, &state_})
      if (!PyType_Check(type->ptr()) ||
          !PyType_IsSubtype(reinterpret_cast<PyTypeObject*>(type->ptr()), &PyTuple_Type))
        throw py::value_error("a controller's step and state are tuple types");
    const auto n = pass.n(), m = evaluator_.m();
    A_.resize(n, n);
    J_.resize(m, n);
    J_H_.resize(m, n);
    x_.resize(n);
    y_.resize(m);
  }

  py::object step(const py::object& q, const py::object& y_dot) {
    auto& pass = evaluator_.pass();
    const auto m = evaluator_.m();
    const double *qi = finite(q, pass.n()), *yi = finite(y_dot, m);
    if (!qi || !yi || !evaluated(qi)) return fallback_(q, y_dot);
    const auto* x_dot = rule_(pass, qi, x_, factors_, J_H_, Vector(yi, m));
    if (!x_dot) return fallback_(q, y_dot);
    factors_.solve(*x_dot, q_dot_);  // q̇ = A⁻¹ ẋ
    if (!x_dot->allFinite() || !q_dot_.allFinite()) return fallback_(q, y_dot);  // it overflowed
    return filled(result_, {array(*x_dot), array(q_dot_), array(y_)});
  }

  // x, A, J_H and M_H = A⁻ᵀ M A⁻¹ at q, by the step's own evaluation.
  py::object state(const py::object& q) {
    const double* qi = finite(q, evaluator_.pass().n());
    if (!qi || !evaluated(qi)) return state_fallback_(q);
    py::object M_H = py::none();
    if (masses_) {
      const Dense& M = evaluator_.pass().mass(qi);
      if (!M.allFinite() || !(M.diagonal().array() > 0).all()) return state_fallback_(q);
      inertia(factors_, M, first_, second_, M_H_);
      M_H = array(M_H_);
    }
    return filled(state_, {array(x_), array(A_), array(J_H_), M_H});
  }

 private:
  // The pass at q, x, A, y, J, the factors of Aᵀ and J_H, as a batch's state is derived
  // (`Evaluator::derived`); false where an actuator cannot be evaluated or A is singular.
  bool evaluated(const double* q) {
    auto& pass = evaluator_.pass();
    pass.at(q, nullptr);
    bool bad = false;
    const auto status = evaluator_
                            .derived(pass.frames(), q, nullptr, x_.data(), A_.data(), y_.data(),
                                     J_.data(), J_H_.data(), factors_, bad)
                            .second;
    return status == OK && !bad;
  }

  // The data of a one-dimensional, contiguous float64 array of `size` finite values, or null.
  static const double* finite(const py::object& value, Eigen::Index size) {
    if (!py::isinstance<py::array_t<double>>(value)) return nullptr;
    const auto array = py::reinterpret_borrow<py::array>(value);
    if (array.ndim() != 1 || array.shape(0) != size || array.strides(0) != py::ssize_t(sizeof(double)))
      return nullptr;
    const auto* data = static_cast<const double*>(array.data());
    return Vector(data, size).allFinite() ? data : nullptr;
  }

  // A tuple of the tuple type `kind` holding `items`, filled as tuple's own constructor fills a
  // subtype's (the type adds no field), without a call into Python.
  static py::object filled(const py::object& kind, std::initializer_list<py::object> items) {
    auto* type = reinterpret_cast<PyTypeObject*>(kind.ptr());
    PyObject* out = type->tp_alloc(type, py::ssize_t(items.size()));
    if (!out) throw py::error_already_set();
    py::ssize_t i = 0;
    for (const auto& item : items) PyTuple_SET_ITEM(out, i++, item.inc_ref().ptr());
    return py::reinterpret_steal<py::object>(out);
  }

  Evaluator evaluator_;
  Rule rule_;
  Matrix A_, J_, J_H_;  // row-major, as `Evaluator::derived` writes them
  Dense M_H_, first_, second_;
  Factors factors_;
  Eigen::VectorXd x_, y_, q_dot_;
  bool masses_;
  py::object fallback_, state_fallback_, result_, state_;
};
