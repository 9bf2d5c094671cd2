// Inverse kinematics (`redundancy.planning.ik.newton`): damped Gauss-Newton on [y; x_h](q) = y*
// for a batch of rows at once, on a compiled pass that reads the task and the held actuators
// (`HeldPass`) or on a Python one.
#pragma once

#include <algorithm>
#include <map>
#include <numeric>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

#include "space.hpp"

// The sign of `value`: −1, 0 or +1.
inline double sign(double value) { return double((value > 0) - (value < 0)); }

// [y; x_h] (m + r) and K = [J; A_h] (m + r, n) of the task rows and r held actuators, read from
// one pass at each of a batch of states.
class HeldPass {
 public:
  HeldPass(const Pass& pass, Eigen::Index tool, std::vector<Eigen::Index> rows,
           const py::array_t<int>& kinds, const py::array_t<Eigen::Index>& slots,
           const Array& numbers)
      : pass_(pass),
        actuation_{tool, std::move(rows), declared(kinds, slots, numbers, pass.size(), pass.n())} {
    if (tool < 0 || tool >= pass_.size() ||
        std::any_of(actuation_.rows.begin(), actuation_.rows.end(),
                    [](auto r) { return r < 0 || r > 2; }))
      throw py::value_error("a held pass takes the tool's slot and its task rows");
  }

  // The joints n, and the values m + r a state gives: its task rows and held actuators.
  Eigen::Index n() const { return pass_.n(); }
  Eigen::Index values() const {
    return Eigen::Index(actuation_.rows.size() + actuation_.actuators.size());
  }

  // The values (u, m + r) and K (u, m + r, n) at q (u, n); nothing where a kind refused a state
  // (Python evaluates it again and raises the kind's error).
  std::optional<std::pair<Matrix, Matrix>> operator()(const Matrix& q) {
    const auto u = q.rows(), n = pass_.n(), m = Eigen::Index(actuation_.rows.size());
    const auto r = Eigen::Index(actuation_.actuators.size()), d = m + r;
    Matrix values(u, d), jacobians(u, d * n), A(r, n), J(m, n);
    Eigen::VectorXd x(r), y(m);
    for (Eigen::Index i = 0; i < u; ++i) {
      pass_.at(q.row(i).data(), nullptr);
      if (actuation_(pass_.frames(), q.row(i).data(), nullptr, x.data(), A.data(), y.data(),
                     J.data())
              .second != OK)
        return std::nullopt;
      values.row(i).head(m) = y;
      values.row(i).tail(r) = x;
      Eigen::Map<Matrix> K(jacobians.row(i).data(), d, n);
      K.topRows(m) = J;
      K.bottomRows(r) = A;
    }
    return std::make_pair(std::move(values), std::move(jacobians));
  }

 private:
  Pass pass_;
  Actuation actuation_;
};

// Damped Gauss-Newton from q (k, n) to [y; x_h](q) = target (k, d): steps δ = (KᵀK + δ₀ I)⁻¹ Kᵀ r,
// each iterate clipped to [lower, upper] (n,) when `bounded`, the joints at a limit the step
// would carry past it held there and the step solved again without them; a row stops once |r| ≤
// `tolerance` or its step moves no coordinate by `stalled` or more. Each configuration is passed
// once: the rows at one share its pass, and so do the rows that come back to one with a joint
// at a limit. `pass` is a `HeldPass` or a Python callable (distinct states (u, n)) → (values
// (u, d), K (u, d, n)); `first`, None or the values and K at q already known (then the first k
// states passed). Returns q, |r| (k,), each row's latest state among the distinct states
// passed in order, and the side of the fold at q, sign det K (k,) where K is square (0
// elsewhere), from the K its last pass read; None where a `HeldPass` refused a state.
inline py::object newton(const py::object& pass, Array start, const Array& target,
                         const py::object& first, int iterations, bool bounded,
                         const Array& lower, const Array& upper, double tolerance, double damping,
                         double stalled) {
  const auto refuse = [] {
    throw py::value_error(
        "newton takes the robot's q (k, n), a target per row (k, m + r) its pass gives, and the "
        "joint limits (n,) each");
  };
  if (start.ndim() != 2 || target.ndim() != 2) refuse();
  const auto k = start.shape(0), n = start.shape(1), d = target.shape(1);
  if (target.shape(0) != k || lower.size() != n || upper.size() != n) refuse();
  if (py::isinstance<HeldPass>(pass)) {
    const auto& held = pass.cast<HeldPass&>();
    if (held.n() != n || held.values() != d) refuse();
  }
  const auto fits = [d, n](const Array& v, const Array& K, py::ssize_t rows) {
    if (v.ndim() != 2 || v.shape(0) != rows || v.shape(1) != d || K.ndim() != 3 ||
        K.shape(0) != rows || K.shape(1) != d || K.shape(2) != n)
      throw py::value_error("a pass gives the values (u, m + r) and K (u, m + r, n) at u states");
  };
  Matrix q = ConstMatrix(start.data(), k, n);
  const ConstMatrix goal(target.data(), k, d);
  Matrix values(k, d), jacobians(k, d * n);
  py::array_t<py::ssize_t> latest(k);
  auto* last = latest.mutable_data();
  py::ssize_t passes = 0;  // distinct states passed so far, in order
  // The states passed so far with a joint at a limit (where clipping brings rows of different
  // targets, and again in a later iteration): their values, K and place among those passed.
  using Entry = std::tuple<Eigen::RowVectorXd, Eigen::RowVectorXd, py::ssize_t>;
  std::map<std::vector<double>, Entry> clipped;
  const auto state = [&](py::ssize_t i) {
    return std::vector<double>(q.row(i).data(), q.row(i).data() + n);
  };
  const auto at_limit = [&](py::ssize_t i) {
    return bounded && ((q.row(i).array() <= Vector(lower.data(), n).transpose().array()) ||
                       (q.row(i).array() >= Vector(upper.data(), n).transpose().array()))
                          .any();
  };
  // The values and K at the rows `active` of q: one pass per distinct configuration not passed
  // yet; each row's place among the states passed in `latest`.
  auto passed = [&](const std::vector<py::ssize_t>& active) -> bool {
    std::vector<py::ssize_t> fresh;
    for (const auto i : active) {
      const auto known = at_limit(i) ? clipped.find(state(i)) : clipped.end();
      if (known == clipped.end()) {
        fresh.push_back(i);
        continue;
      }
      const auto& [v, K, place] = known->second;
      values.row(i) = v;
      jacobians.row(i) = K;
      last[i] = place;
    }
    if (fresh.empty()) return true;
    std::vector<py::ssize_t> order(fresh.size());
    std::iota(order.begin(), order.end(), 0);
    auto row = [&](py::ssize_t a) { return q.row(fresh[a]); };
    auto less = [&](py::ssize_t a, py::ssize_t b) {
      return std::lexicographical_compare(row(a).begin(), row(a).end(), row(b).begin(),
                                          row(b).end());
    };
    std::stable_sort(order.begin(), order.end(), less);
    std::vector<py::ssize_t> inverse(fresh.size()), unique;
    for (std::size_t j = 0; j < order.size(); ++j) {
      if (j == 0 || row(order[j]) != row(order[j - 1])) unique.push_back(order[j]);
      inverse[order[j]] = py::ssize_t(unique.size()) - 1;
    }
    Matrix states(unique.size(), n);
    for (std::size_t j = 0; j < unique.size(); ++j) states.row(j) = row(unique[j]);
    Matrix found_values, found_jacobians;
    if (py::isinstance<HeldPass>(pass)) {
      auto found = pass.cast<HeldPass&>()(states);
      if (!found) return false;
      std::tie(found_values, found_jacobians) = std::move(*found);
    } else {
      Array unique_states({py::ssize_t(states.rows()), py::ssize_t(n)});
      at(unique_states, 0, states.rows(), n) = states;
      const auto out = pass(unique_states).cast<py::tuple>();
      const auto v = out[0].cast<Array>(), K = out[1].cast<Array>();
      fits(v, K, states.rows());
      found_values = ConstMatrix(v.data(), states.rows(), d);
      found_jacobians = ConstMatrix(K.data(), states.rows(), d * n);
    }
    for (std::size_t a = 0; a < fresh.size(); ++a) {
      const auto i = fresh[a];
      values.row(i) = found_values.row(inverse[a]);
      jacobians.row(i) = found_jacobians.row(inverse[a]);
      last[i] = passes + inverse[a];
      if (at_limit(i)) clipped.try_emplace(state(i), values.row(i), jacobians.row(i), last[i]);
    }
    passes += py::ssize_t(unique.size());
    return true;
  };
  std::vector<py::ssize_t> active(k);
  std::iota(active.begin(), active.end(), 0);
  if (first.is_none()) {
    if (!passed(active)) return py::none();
  } else {
    const auto known = first.cast<py::tuple>();
    const auto v = known[0].cast<Array>(), K = known[1].cast<Array>();
    fits(v, K, k);
    values = ConstMatrix(v.data(), k, d);
    jacobians = ConstMatrix(K.data(), k, d * n);
    std::iota(last, last + k, 0);
    passes = k;
  }
  Matrix residual = values - goal;
  const Eigen::MatrixXd eye = damping * Eigen::MatrixXd::Identity(n, n);
  for (int iteration = 0; iteration < iterations; ++iteration) {
    std::vector<py::ssize_t> moving;
    for (const auto i : active) {
      if (!(residual.row(i).norm() > tolerance)) continue;
      const ConstMatrix K(jacobians.row(i).data(), d, n);
      const auto step = [&](const auto& jacobian) -> Eigen::VectorXd {
        return (jacobian.transpose() * jacobian + eye)
            .partialPivLu()
            .solve(jacobian.transpose() * residual.row(i).transpose());
      };
      Eigen::RowVectorXd updated = q.row(i) - step(K).transpose();
      if (bounded) {
        // A joint at a limit the step would carry past it stays there, and the step is solved
        // again without it: the other joints then make the whole of their way (an active set).
        Matrix free;  // K without the columns of the joints held
        for (Eigen::Index j = 0; j < n; ++j) {
          const double low = lower.data()[j], high = upper.data()[j];
          if ((q(i, j) <= low && updated[j] < low) || (q(i, j) >= high && updated[j] > high)) {
            if (!free.size()) free = K;
            free.col(j).setZero();
          }
        }
        if (free.size()) updated = q.row(i) - step(free).transpose();
        updated = updated.cwiseMax(Vector(lower.data(), n).transpose())
                      .cwiseMin(Vector(upper.data(), n).transpose());
      }
      if (!((updated - q.row(i)).cwiseAbs().array() < stalled).all()) {
        q.row(i) = updated;
        moving.push_back(i);
      }
    }
    active = std::move(moving);
    if (active.empty()) break;
    if (!passed(active)) return py::none();
    for (const auto i : active) residual.row(i) = values.row(i) - goal.row(i);
  }
  Array solved({k, n}), miss(k), side(k);
  at(solved, 0, k, n) = q;
  for (py::ssize_t i = 0; i < k; ++i) {
    miss.mutable_data()[i] = residual.row(i).norm();
    const ConstMatrix K(jacobians.row(i).data(), d, n);
    side.mutable_data()[i] = d == n ? sign(K.partialPivLu().determinant()) : 0.0;
  }
  return py::make_tuple(solved, miss, latest, side);
}
