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

// The values (u, d) and K (u, d·n) of a pass's answer (values (u, d), K (u, d, n)) at u states
// of n joints, its shapes checked.
inline std::pair<Matrix, Matrix> pass_answer(const py::tuple& out, py::ssize_t u,
                                             Eigen::Index d, Eigen::Index n) {
  const auto v = out[0].cast<Array>(), K = out[1].cast<Array>();
  if (v.ndim() != 2 || v.shape(0) != u || v.shape(1) != d || K.ndim() != 3 ||
      K.shape(0) != u || K.shape(1) != d || K.shape(2) != n)
    throw py::value_error("a pass gives the values (u, m + r) and K (u, m + r, n) at u states");
  return {ConstMatrix(v.data(), u, d), ConstMatrix(K.data(), u, d * n)};
}

// The values (u, d) and K (u, d·n) at the states (u, n) by `pass`, a `HeldPass` or a Python
// callable (states (u, n)) → (values (u, d), K (u, d, n)); nothing where a `HeldPass` refused a
// state.
inline std::optional<std::pair<Matrix, Matrix>> read_pass(const py::object& pass,
                                                          const Matrix& states, Eigen::Index d) {
  if (py::isinstance<HeldPass>(pass)) return pass.cast<HeldPass&>()(states);
  const auto u = states.rows(), n = states.cols();
  Array given({py::ssize_t(u), py::ssize_t(n)});
  at(given, 0, u, n) = states;
  return pass_answer(pass(given).cast<py::tuple>(), u, d, n);
}

// Where Newton ended: q (k, n), |r| (k), the side of the fold sign det K (k) where K is square
// (0 elsewhere), and each row's latest state among the distinct states passed, in order.
struct Solved {
  Matrix q;
  Eigen::VectorXd miss, side;
  std::vector<py::ssize_t> latest;
};

// Damped Gauss-Newton from q (k, n) to [y; x_h](q) = goal (k, d): steps δ = (KᵀK + δ₀ I)⁻¹ Kᵀ r,
// each iterate clipped to [lower, upper] (n) when `bounded`, the joints at a limit the step
// would carry past it held there and the step solved again without them; a row stops once |r| ≤
// `tolerance` or its step moves no coordinate by `stalled` or more. Each configuration is passed
// once: the rows at one share its pass, and so do the rows that come back to one with a joint
// at a limit. `pass` is read by `read_pass`; `first`, nothing or the values and K at q already
// known (then the first k states passed). Nothing where a `HeldPass` refused a state.
inline std::optional<Solved> gauss_newton(const py::object& pass, Matrix q, const Matrix& goal,
                                          const std::optional<std::pair<Matrix, Matrix>>& first,
                                          int iterations, bool bounded,
                                          const Eigen::RowVectorXd& lower,
                                          const Eigen::RowVectorXd& upper, double tolerance,
                                          double damping, double stalled) {
  const auto k = q.rows(), n = q.cols(), d = goal.cols();
  Matrix values(k, d), jacobians(k, d * n);
  std::vector<py::ssize_t> last(std::size_t(k), 0);
  py::ssize_t passes = 0;  // distinct states passed so far, in order
  // The states passed so far with a joint at a limit (where clipping brings rows of different
  // targets, and again in a later iteration): their values, K and place among those passed.
  using Entry = std::tuple<Eigen::RowVectorXd, Eigen::RowVectorXd, py::ssize_t>;
  std::map<std::vector<double>, Entry> clipped;
  const auto state = [&](py::ssize_t i) {
    return std::vector<double>(q.row(i).data(), q.row(i).data() + n);
  };
  const auto at_limit = [&](py::ssize_t i) {
    return bounded && ((q.row(i).array() <= lower.array()) || (q.row(i).array() >= upper.array()))
                          .any();
  };
  // The values and K at the rows `active` of q: one pass per distinct configuration not passed
  // yet; each row's place among the states passed in `last`.
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
      last[std::size_t(i)] = place;
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
    const auto found = read_pass(pass, states, d);
    if (!found) return false;
    const auto& [found_values, found_jacobians] = *found;
    for (std::size_t a = 0; a < fresh.size(); ++a) {
      const auto i = fresh[a];
      values.row(i) = found_values.row(inverse[a]);
      jacobians.row(i) = found_jacobians.row(inverse[a]);
      last[std::size_t(i)] = passes + inverse[a];
      if (at_limit(i))
        clipped.try_emplace(state(i), values.row(i), jacobians.row(i), last[std::size_t(i)]);
    }
    passes += py::ssize_t(unique.size());
    return true;
  };
  std::vector<py::ssize_t> active(k);
  std::iota(active.begin(), active.end(), 0);
  if (!first) {
    if (!passed(active)) return std::nullopt;
  } else {
    std::tie(values, jacobians) = *first;
    std::iota(last.begin(), last.end(), 0);
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
          if ((q(i, j) <= lower[j] && updated[j] < lower[j]) ||
              (q(i, j) >= upper[j] && updated[j] > upper[j])) {
            if (!free.size()) free = K;
            free.col(j).setZero();
          }
        }
        if (free.size()) updated = q.row(i) - step(free).transpose();
        updated = updated.cwiseMax(lower).cwiseMin(upper);
      }
      if (!((updated - q.row(i)).cwiseAbs().array() < stalled).all()) {
        q.row(i) = updated;
        moving.push_back(i);
      }
    }
    active = std::move(moving);
    if (active.empty()) break;
    if (!passed(active)) return std::nullopt;
    for (const auto i : active) residual.row(i) = values.row(i) - goal.row(i);
  }
  Solved out{std::move(q), Eigen::VectorXd(k), Eigen::VectorXd(k), std::move(last)};
  for (py::ssize_t i = 0; i < k; ++i) {
    out.miss[i] = residual.row(i).norm();
    const ConstMatrix K(jacobians.row(i).data(), d, n);
    out.side[i] = d == n ? sign(K.partialPivLu().determinant()) : 0.0;
  }
  return out;
}

// A row vector's copy of a numpy vector (n,).
inline Eigen::RowVectorXd row_of(const Array& a) {
  return Eigen::Map<const Eigen::RowVectorXd>(a.data(), a.size());
}

// `gauss_newton` from Python: q (k, n) to the targets (k, m + r) the pass gives, the joint
// limits (n,) each, `first` None or (values, K) at q. Returns q, |r| (k,), each row's latest
// state among the distinct states passed in order, and the side of the fold at q (k,); None
// where a `HeldPass` refused a state.
inline py::object newton(const py::object& pass, const Array& start, const Array& target,
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
  std::optional<std::pair<Matrix, Matrix>> known;
  if (!first.is_none()) known = pass_answer(first.cast<py::tuple>(), k, d, n);
  const auto solved = gauss_newton(pass, ConstMatrix(start.data(), k, n),
                                   ConstMatrix(target.data(), k, d), known, iterations, bounded,
                                   row_of(lower), row_of(upper), tolerance, damping, stalled);
  if (!solved) return py::none();
  py::array_t<py::ssize_t> latest(k);
  std::copy(solved->latest.begin(), solved->latest.end(), latest.mutable_data());
  return py::make_tuple(array(solved->q), array(solved->miss), latest, array(solved->side));
}

// An angle (rad) within [−π, π), a whole number of turns from `angle`, as numpy's remainder of
// angle + π by 2π, less π (`redundancy.model.values.modulo_turn`).
inline double modulo_turn(double angle) {
  constexpr double turn = 2 * M_PI;
  double rest = std::fmod(angle + M_PI, turn);
  if (rest < 0) rest += turn;
  if (rest == 0) rest = 0.0;  // +0, as numpy's
  return rest - M_PI;
}

// Continuation along one held actuator (`redundancy.planning.ik.continue_held`): configurations
// reaching `point` (m) with the held actuator at `values` (k), each by `gauss_newton` (unbounded,
// `iterations`) from the known configuration (held values (j), q (j, n), sides of the fold (j))
// whose value is nearest, the first such in their order, and again from a nearer one whenever a
// pass finds one. A configuration found counts on its origin's side of the fold alone. Each is
// then moved by whole turns, in each `bounded` joint (a revolute joint whose range spans at most
// a turn), first to the turn nearest its origin's value, then, where that lies outside the
// joint's range and a turn up or down lies inside it, to that turn (Newton from far away can land
// on the pose a turn or more away; a slew whose stroke is one turn, crossing its end, comes back
// inside it a turn away): kept where some joint moved by more than π and the moved configuration
// still meets the target to `found` (a held actuator driving a joint directly then does not), its
// side read again there (a Python pass raises a kind's error there, as in Newton). Returns q
// (k, n) (zeros at a value not finite, never tried), the residuals (k) (below `found` where
// found) and the sides (k); None where a `HeldPass` refused a state during Newton.
inline py::object continue_held(const py::object& pass, const Array& point,
                                const Array& known_values, const Array& known_q,
                                const Array& known_sides, const Array& values, int iterations,
                                const Array& lower, const Array& upper,
                                const py::array_t<bool, py::array::c_style | py::array::forcecast>&
                                    bounded,
                                double tolerance, double damping, double stalled, double found) {
  const auto m = point.size(), n = known_q.ndim() == 2 ? known_q.shape(1) : 0, d = m + 1;
  const auto j = known_values.size(), k = values.size();
  if (point.ndim() != 1 || known_values.ndim() != 1 || known_q.ndim() != 2 || n != d ||
      (j < 1 && k > 0) || known_q.shape(0) != j || known_sides.size() != j ||
      values.ndim() != 1 || lower.size() != n || upper.size() != n || bounded.size() != n)
    throw py::value_error(
        "continue_held takes the point (m,) of a robot of n = m + 1 joints, known values (j,), "
        "q (j, n) and sides (j,), at least one where values (k,) are asked, and the joint limits "
        "and bounded joints (n,) each");
  if (py::isinstance<HeldPass>(pass)) {
    const auto& held = pass.cast<HeldPass&>();
    if (held.n() != n || held.values() != d)
      throw py::value_error("continue_held takes the pass of the task and one held actuator");
  }
  std::vector<double> origins(known_values.data(), known_values.data() + j);
  std::vector<double> sides(known_sides.data(), known_sides.data() + j);
  Matrix configurations = ConstMatrix(known_q.data(), j, n);
  const auto low = row_of(lower), high = row_of(upper);
  const Eigen::Map<const Eigen::RowVectorXd> y(point.data(), m);
  const auto* wanted = values.data();
  Matrix q = Matrix::Zero(k, n);
  Eigen::VectorXd residual = Eigen::VectorXd::Constant(k, INFINITY);
  Eigen::VectorXd side = Eigen::VectorXd::Zero(k);
  std::vector<double> tried(std::size_t(k), INFINITY);  // distance of the value last continued from
  std::vector<py::ssize_t> pending(k);
  std::iota(pending.begin(), pending.end(), 0);
  while (!pending.empty()) {
    std::vector<py::ssize_t> rows, nearest;
    for (const auto i : pending) {  // the first nearest known value; none past a NaN, as numpy
      py::ssize_t best = 0;
      double least = std::abs(wanted[i] - origins[0]);
      for (std::size_t a = 1; a < origins.size() && !std::isnan(least); ++a) {
        const double distance = std::abs(wanted[i] - origins[a]);
        if (distance < least || std::isnan(distance)) least = distance, best = py::ssize_t(a);
      }
      if (!(least < tried[std::size_t(i)])) continue;
      tried[std::size_t(i)] = least;
      rows.push_back(i);
      nearest.push_back(best);
    }
    if (rows.empty()) break;
    const auto r = py::ssize_t(rows.size());
    Matrix start(r, n), goal(r, d);
    for (py::ssize_t a = 0; a < r; ++a) {
      start.row(a) = configurations.row(nearest[a]);
      goal.row(a) << y, wanted[rows[a]];
    }
    auto solved = gauss_newton(pass, start, goal, std::nullopt, iterations, false, low, high,
                               tolerance, damping, stalled);
    if (!solved) return py::none();
    // the turns: each found row's configuration moved to its nearest turn inside the ranges
    std::vector<py::ssize_t> turned;
    Matrix moved = solved->q;
    for (py::ssize_t a = 0; a < r; ++a) {
      if (!(solved->miss[a] < found)) continue;
      bool far = false;
      for (Eigen::Index c = 0; c < n; ++c) {
        if (!bounded.data()[c]) continue;
        const double origin = start(a, c), value = solved->q(a, c);
        double nearest_turn = origin + modulo_turn(value - origin);
        for (const double turn : {2 * M_PI, -2 * M_PI}) {
          const bool inside = nearest_turn >= low[c] && nearest_turn <= high[c];
          const double other = nearest_turn + turn;
          if (!inside && other >= low[c] && other <= high[c]) nearest_turn = other;
        }
        moved(a, c) = nearest_turn;
        far = far || std::abs(nearest_turn - value) > M_PI;
      }
      if (far) turned.push_back(a);
    }
    for (const auto a : turned) {  // one at a time: one the compiled pass refuses is not kept
      const auto there = read_pass(pass, moved.row(a), d);
      if (!there || !((there->first.row(0) - goal.row(a)).norm() < found)) continue;
      solved->q.row(a) = moved.row(a);
      solved->side[a] = sign(ConstMatrix(there->second.data(), d, n).partialPivLu().determinant());
    }
    std::vector<py::ssize_t> still;
    for (py::ssize_t a = 0; a < r; ++a) {
      const auto i = rows[a];
      q.row(i) = solved->q.row(a);
      residual[i] = solved->miss[a];
      if (!(residual[i] < found)) {
        still.push_back(i);
        continue;
      }
      side[i] = solved->side[a];
      if (side[i] != sides[std::size_t(nearest[a])]) {  // the other branch: not found
        residual[i] = INFINITY;
        still.push_back(i);
        continue;
      }
      origins.push_back(wanted[i]);
      sides.push_back(side[i]);
      configurations.conservativeResize(configurations.rows() + 1, Eigen::NoChange);
      configurations.row(configurations.rows() - 1) = q.row(i);
    }
    pending = std::move(still);
  }
  return py::make_tuple(array(q), array(residual), array(side));
}
