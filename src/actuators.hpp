// The built-in actuator kinds: x, a row of A = ∂x/∂q and, moving, a row of Ȧ at one state, read
// from the tracked frames (`Frames`) of the one pass.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "pass.hpp"

using Block = Eigen::Matrix<double, 3, Eigen::Dynamic>;
using RowOut = Eigen::Map<Eigen::RowVectorXd>;

// What a kind could not do at a state; Python names the actuator in the error it raises.
enum Status : std::int8_t { OK = 0, ZERO_LENGTH = 1, OPEN_LOOP = 2 };

// An actuator as Python declares it to the core: its kind, the slots among the tracked frames
// it reads (as many as the kind needs) and its numbers.
//   IDENTITY  x = q_j + offset:                        numbers (j, offset)
//   CYLINDER  x = |p_rod − p_base|:                    slots (base, rod)
//   LINKAGE   x = |P − b|, P closing a four-bar:       slots (b, R, R + n, C),
//                                                      numbers (rocker r, coupler c, branch σ)
struct Actuator {
  enum Kind : int { IDENTITY = 0, CYLINDER = 1, LINKAGE = 2 } kind;
  std::array<Eigen::Index, 4> slots;
  std::array<double, 3> numbers;
};

// x = |d| and its row of A, uᵀ ∂d/∂q (u = d / x), for ∂d/∂q `J` (3, n), an expression read as it
// is multiplied (no copy). A zero length (the ends coincide) is refused.
template <class Jacobian>
Status span(const Eigen::Vector3d& d, const Jacobian& J, double& x, RowOut row) {
  x = d.norm();
  if (!(x >= 1e-12) && std::isfinite(x)) return ZERO_LENGTH;
  row.noalias() = (d / x).transpose().lazyProduct(J);
  return OK;
}

// The row of Ȧ of x = |d| (`span`), u̇ᵀ ∂d/∂q + uᵀ d(∂d/∂q)/dt with u̇ = (I − u uᵀ) ḋ / x, from
// the rates ḋ and d(∂d/∂q)/dt.
template <class Jacobian, class Rate>
void span_rate(const Eigen::Vector3d& d, double x, const Jacobian& J,
               const Eigen::Vector3d& d_dot, const Rate& J_dot, RowOut rate) {
  const Eigen::Vector3d u = d / x;
  const Eigen::Vector3d u_dot = (d_dot - u * u.dot(d_dot)) / x;
  rate.noalias() = u_dot.transpose().lazyProduct(J) + u.transpose().lazyProduct(J_dot);
}

// The four-bar's closure (module docstring of `redundancy.model.linkage`): P in the plane through
// R normal to n, |P − R| = r, |P − C| = c, on the branch σ; J_P and J̇_P by implicit
// differentiation of the loop equations, M J_P = K and M J̇_P = K̇ − Ṁ J_P. x and its rows follow
// as for a cylinder from b to P. `pin` receives P.
inline Status linkage(const Actuator& a, const Frames& s, const double* v, double& x, RowOut row,
                      RowOut* rate, Eigen::Vector3d& pin) {
  const auto [b_, R_, tip_, C_] = a.slots;
  const double r = a.numbers[0], c = a.numbers[1], sigma = a.numbers[2];
  const Eigen::Vector3d b = s.position(b_), R = s.position(R_), C = s.position(C_);
  const Eigen::Vector3d axis = s.position(tip_) - R, w = C - R;
  const double h = axis.dot(w);
  const Eigen::Vector3d w_plane = w - h * axis;
  const double d = w_plane.norm();
  const double along = (r * r - (c * c - h * h) + d * d) / (2 * d);
  const double height2 = r * r - along * along;
  if (!(height2 >= 0)) {
    x = std::numeric_limits<double>::quiet_NaN();
    return OPEN_LOOP;
  }
  const Eigen::Vector3d e1 = w_plane / d, e2 = axis.cross(e1);
  pin = R + along * e1 + sigma * std::sqrt(height2) * e2;
  const Block J_b = s.jacobian(b_), J_R = s.jacobian(R_), J_C = s.jacobian(C_);
  const Block J_n = s.jacobian(tip_) - J_R;
  const Eigen::Vector3d to_R = pin - R, to_C = pin - C;
  Eigen::Matrix3d M;
  M << to_R.transpose(), to_C.transpose(), axis.transpose();
  Block K(3, s.n);
  K << to_R.transpose() * J_R, to_C.transpose() * J_C,
      axis.transpose() * J_R - to_R.transpose() * J_n;
  const auto solver = M.partialPivLu();
  const Block J_P = solver.solve(K);
  const auto status = span(pin - b, J_P - J_b, x, row);
  if (!rate || status != OK) return status;
  const Block Jd_R = s.rate(R_), Jd_C = s.rate(C_), Jd_n = s.rate(tip_) - Jd_R;
  const Eigen::Vector3d v_R = s.velocity(R_), v_C = s.velocity(C_);
  const Eigen::Vector3d v_n = s.velocity(tip_) - v_R;
  const Eigen::Vector3d v_P = J_P * Vector(v, s.n);
  Eigen::Matrix3d M_dot;
  M_dot << (v_P - v_R).transpose(), (v_P - v_C).transpose(), v_n.transpose();
  Block K_dot(3, s.n);
  K_dot << (v_P - v_R).transpose() * J_R + to_R.transpose() * Jd_R,
      (v_P - v_C).transpose() * J_C + to_C.transpose() * Jd_C,
      v_n.transpose() * J_R + axis.transpose() * Jd_R - (v_P - v_R).transpose() * J_n -
          to_R.transpose() * Jd_n;
  const Block Jd_P = solver.solve(K_dot - M_dot * J_P);
  const Eigen::Vector3d d_dot = v_P - s.velocity(b_);
  span_rate(pin - b, x, J_P - J_b, d_dot, Jd_P - s.rate(b_), *rate);
  return OK;
}

// x, the row of A and, if `rate`, the row of Ȧ of one actuator at one state (q, v (n) or null);
// `end` receives the point its rod ends at (NaN for a joint driven directly).
inline Status actuate(const Actuator& a, const Frames& s, const double* q, const double* v,
                      double& x, RowOut row, RowOut* rate, Eigen::Vector3d& end) {
  switch (a.kind) {
    case Actuator::IDENTITY: {
      const auto j = Eigen::Index(a.numbers[0]);
      x = q[j] + a.numbers[1];
      row.setZero();
      row[j] = 1.0;
      if (rate) rate->setZero();
      end.setConstant(std::numeric_limits<double>::quiet_NaN());
      return OK;
    }
    case Actuator::CYLINDER: {
      const auto base = a.slots[0], rod = a.slots[1];
      end = s.position(rod);
      const Eigen::Vector3d d = end - s.position(base);
      const auto J = s.jacobian(rod) - s.jacobian(base);
      const auto status = span(d, J, x, row);
      if (!rate || status != OK) return status;
      span_rate(d, x, J, s.velocity(rod) - s.velocity(base), s.rate(rod) - s.rate(base), *rate);
      return OK;
    }
    case Actuator::LINKAGE:
      return linkage(a, s, v, x, row, rate, end);
  }
  return OK;
}

// The actuators declared by Python: kinds (c,), slots (c, 4) and numbers (c, 3), checked against
// the F tracked frames and n joints.
inline std::vector<Actuator> declared(const py::array_t<int>& kinds,
                                      const py::array_t<Eigen::Index>& slots,
                                      const Array& numbers, Eigen::Index F, Eigen::Index n) {
  const auto c = kinds.size();
  if (kinds.ndim() != 1 || slots.ndim() != 2 || slots.shape(0) != c || slots.shape(1) != 4 ||
      numbers.ndim() != 2 || numbers.shape(0) != c || numbers.shape(1) != 3)
    throw py::value_error("actuators are kinds (c,), slots (c, 4) and numbers (c, 3)");
  std::vector<Actuator> out(c);
  for (py::ssize_t i = 0; i < c; ++i) {
    auto& a = out[i];
    a.kind = Actuator::Kind(kinds.at(i));
    for (int j = 0; j < 4; ++j) a.slots[j] = slots.at(i, j);
    for (int j = 0; j < 3; ++j) a.numbers[j] = numbers.at(i, j);
    const int read = a.kind == Actuator::CYLINDER ? 2 : a.kind == Actuator::LINKAGE ? 4 : 0;
    const bool frames_ok = std::all_of(a.slots.begin(), a.slots.begin() + read,
                                       [F](auto f) { return 0 <= f && f < F; });
    const bool joint_ok = a.kind != Actuator::IDENTITY || (0 <= a.numbers[0] && a.numbers[0] < n);
    if (a.kind < Actuator::IDENTITY || a.kind > Actuator::LINKAGE || !frames_ok || !joint_ok)
      throw py::value_error("actuator " + std::to_string(i) + " is not a kind the core knows");
  }
  return out;
}

// x (k, c), rows of A (k, c, n), with velocities rows of Ȧ (k, c, n) (else None), the rods'
// ends (k, c, 3) and each one's `Status` (k, c) of c actuators at k states, from the pass's
// arrays: q (k, n), positions (k, F, 3), jacobians (k, F, 3, n), and moving v (k, n),
// velocities (k, F, 3), rates (k, F, 3, n).
inline py::tuple actuate_batch(const py::array_t<int>& kinds,
                               const py::array_t<Eigen::Index>& slots, const Array& numbers,
                               const Array& q, const Array& positions, const Array& jacobians,
                               const std::optional<Array>& v,
                               const std::optional<Array>& velocities,
                               const std::optional<Array>& rates) {
  if (q.ndim() != 2 || positions.ndim() != 3 || jacobians.ndim() != 4 ||
      positions.shape(0) != q.shape(0) || jacobians.shape(0) != q.shape(0) ||
      positions.shape(2) != 3 || jacobians.shape(1) != positions.shape(1) ||
      jacobians.shape(2) != 3 || jacobians.shape(3) != q.shape(1))
    throw py::value_error("actuate takes q (k, n), positions (k, F, 3), jacobians (k, F, 3, n)");
  const auto k = q.shape(0), n = q.shape(1), F = positions.shape(1);
  const bool moving = v.has_value();
  if (moving != velocities.has_value() || moving != rates.has_value() ||
      (moving && (v->size() != q.size() || velocities->size() != positions.size() ||
                  rates->size() != jacobians.size())))
    throw py::value_error("actuate's v, velocities and rates come together, shaped as the pass's");
  const auto actuators = declared(kinds, slots, numbers, F, n);
  const auto c = py::ssize_t(actuators.size());
  Array x({k, c}), rows({k, c, n}), ends({k, c, py::ssize_t(3)});
  py::array_t<std::int8_t> status({k, c});
  py::object rate_rows = py::none();
  double* out_rate = nullptr;
  if (moving) {
    Array made({k, c, n});
    out_rate = made.mutable_data();
    rate_rows = made;
  }
  Eigen::Vector3d end;
  for (py::ssize_t i = 0; i < k; ++i) {
    const Frames s{positions.data() + i * F * 3, jacobians.data() + i * F * 3 * n,
                   moving ? velocities->data() + i * F * 3 : nullptr,
                   moving ? rates->data() + i * F * 3 * n : nullptr, n};
    for (py::ssize_t j = 0; j < c; ++j) {
      const auto at = i * c + j;
      RowOut rate(out_rate ? out_rate + at * n : nullptr, n);
      status.mutable_data()[at] =
          actuate(actuators[j], s, q.data() + i * n, moving ? v->data() + i * n : nullptr,
                  x.mutable_data()[at], RowOut(rows.mutable_data() + at * n, n),
                  out_rate ? &rate : nullptr, end);
      Eigen::Map<Eigen::Vector3d>(ends.mutable_data() + 3 * at) = end;
    }
  }
  return py::make_tuple(x, rows, rate_rows, ends, status);
}
