// The adaptive integration of a law along a segment (`redundancy.planning.integrate`): the
// Dormand-Prince 5(4) loop over a batch of starts, each with its own step size, and the compiled
// right-hand side q̇(t, q) of a built-in law on built-in kinds (`Rates`).
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "rule.hpp"

// What a right-hand side gives at r states: q̇ (r, n), where the state is bad (r,) (A singular or
// not finite: there q̇ = 0), the strokes x (r, n), and its record of the states (kept, for the
// ends of accepted steps, where the integration samples them).
struct Stage {
  py::object record;
  Array q_dot, x;
  py::array_t<bool> bad;
};

// The task velocity ẏ (r, m) at times t (r,) where the tool is at y (r, m): `velocity` is ẏ
// itself, (m,), where it is constant along the path; (y_d(0), ẏ_d, K) on such a path in closed
// loop, ẏ = ẏ_d + K (y_d(0) + ẏ_d t − y); or a Python callable (t, y) → ẏ (r, m).
inline Array task_velocity(const py::object& velocity, const Array& t, const py::object& y,
                           py::ssize_t m) {
  const auto r = t.shape(0);
  const auto constant = [m](const py::handle& value) {
    const auto out = value.cast<Array>();
    if (out.ndim() != 1 || out.shape(0) != m)
      throw py::value_error("a constant ẏ_d and its path's start must have shape (m,)");
    return out;
  };
  if (py::isinstance<Array>(velocity)) {
    const auto steady = constant(velocity);
    Array out({r, m});
    for (py::ssize_t i = 0; i < r; ++i) at(out, i, 1, m) = at(steady, 0, 1, m);
    return out;
  }
  if (py::isinstance<py::tuple>(velocity)) {
    const auto loop = velocity.cast<py::tuple>();
    if (loop.size() != 3) throw py::value_error("a closed loop is (y_d(0), ẏ_d, K)");
    const auto start = constant(loop[0]), steady = constant(loop[1]);
    const double gain = loop[2].cast<double>();
    const auto tool = y.cast<Array>();
    Array out({r, m});
    for (py::ssize_t i = 0; i < r; ++i) {
      const auto target = at(start, 0, 1, m) + t.at(i) * at(steady, 0, 1, m);
      at(out, i, 1, m) = at(steady, 0, 1, m) + gain * (target - at(tool, i, 1, m));
    }
    return out;
  }
  const Array out = velocity(t, y);
  if (out.ndim() != 2 || out.shape(0) != r || out.shape(1) != m)
    throw py::value_error("the task velocity must have shape (r, m)");
  return out;
}

// q̇(t, q) = A⁻¹ ẋ of a built-in law at states evaluated by the compiled `Evaluator`, for the
// task velocity given by `velocity` (`task_velocity`: constant, with its closed loop on a
// steady path, or one call of Python per batch): a weighted pseudoinverse (`Rule`), or a held
// law (`Held`) whose held actuators' rates `held(t, x_h)` → (r, h) Python gives, once per
// batch, from the times and their strokes. Its record is (the evaluator's tuple, ẋ, q̇), which
// is also what a call from Python returns (`Law.__call__`: the first states, the samples between
// steps and on a grid). A state a kind refused is bad, as where A is singular. None where the
// core cannot serve the states (Python evaluates them again and raises its error).
class Rates {
 public:
  Rates(py::object evaluator, int weight, const std::optional<Array>& W,
        const std::optional<Array>& pull, const std::optional<Array>& middle, double ratio)
      : evaluator_(std::move(evaluator)) {
    rule_.emplace(evaluator_.cast<Evaluator&>().pass().n(), weight, W, pull, middle, ratio);
  }

  Rates(py::object evaluator, std::vector<Eigen::Index> rows, py::object held)
      : evaluator_(std::move(evaluator)), rates_(std::move(held)) {
    held_.emplace(std::move(rows), evaluator_.cast<Evaluator&>().pass().n());
  }

  std::optional<Stage> operator()(const Array& t, const Array& q, const py::object& velocity) {
    auto& evaluator = evaluator_.cast<Evaluator&>();
    const py::object found = evaluator.evaluate(q, py::none(), false, &factors_);
    if (found.is_none()) return std::nullopt;
    const auto evaluated = found.cast<py::tuple>();
    const auto x = evaluated[7].cast<Array>(), A = evaluated[8].cast<Array>();
    const auto J_H = evaluated[11].cast<Array>();
    auto bad = evaluated[12].cast<py::array_t<bool>>();
    const auto r = q.shape(0), n = q.shape(1), m = J_H.shape(1);
    if (t.ndim() != 1 || t.shape(0) != r)
      throw py::value_error("t must have shape (r,), one time per state");
    const Array y_dot = task_velocity(velocity, t, evaluated[9], m);
    std::optional<Array> targets;  // a held law's rates (r, h)
    if (held_) targets = held_rates(t, x);
    const auto h = targets ? targets->shape(1) : 0;
    Array x_dot({r, n}), q_dot({r, n});
    auto* flags = bad.mutable_data();
    for (py::ssize_t i = 0; i < r; ++i) {
      auto xi = at(x_dot, i, 1, n).transpose();
      auto vi = at(q_dot, i, 1, n).transpose();
      xi.setZero();
      vi.setZero();
      if (flags[i]) continue;
      auto& factors = factors_[std::size_t(i)];  // of Aᵀ, as the evaluation derived them
      const auto y_dot_i = at(y_dot, i, 1, m).transpose();
      const auto* solved =
          held_ ? (*held_)(at(J_H, i, m, n), y_dot_i, at(*targets, i, 1, h).transpose())
                : (*rule_)(evaluator.pass(), q.data() + i * n, at(x, i, 1, n).transpose(),
                           factors, at(J_H, i, m, n), y_dot_i);
      if (!solved) return std::nullopt;
      factors.solve(*solved, vi);  // q̇ = A⁻¹ ẋ
      if (!vi.allFinite()) {
        flags[i] = true;
        vi.setZero();
        continue;
      }
      xi = *solved;
    }
    return Stage{py::make_tuple(evaluated, x_dot, q_dot), q_dot, x, bad};
  }

 private:
  // The held actuators' rates (r, h) at times t (r,), from their strokes among x (r, n).
  Array held_rates(const Array& t, const Array& x) const {
    const auto& rows = held_->rows();
    const auto r = x.shape(0), n = x.shape(1), h = py::ssize_t(rows.size());
    Array strokes({r, h});
    for (py::ssize_t i = 0; i < r; ++i)
      for (py::ssize_t j = 0; j < h; ++j)
        strokes.mutable_at(i, j) = x.data()[i * n + rows[std::size_t(j)]];
    const Array out = rates_(t, strokes);
    if (out.ndim() != 2 || out.shape(0) != r || out.shape(1) != h)
      throw py::value_error("the held actuators' rates must have shape (r, h)");
    return out;
  }

  py::object evaluator_;
  std::optional<Rule> rule_;
  std::optional<Held> held_;
  py::object rates_;  // a held law's rates, a Python callable (t, x_h) → (r, h)
  std::vector<Factors> factors_;  // each state's, kept by the evaluation for the solves here
};

// A right-hand side at r states: `Rates` in C++, or a Python callable (t, q) → (record, q̇, bad, x).
inline std::optional<Stage> rates_at(const py::object& rates, const py::object& velocity,
                                     const Array& t, const Array& q) {
  if (py::isinstance<Rates>(rates)) return rates.cast<Rates&>()(t, q, velocity);
  const auto out = rates(t, q).cast<py::tuple>();
  return Stage{out[0], out[1].cast<Array>(), out[3].cast<Array>(), out[2].cast<py::array_t<bool>>()};
}

// Dormand-Prince 5(4) with error control on q, every start with its own step size (the module
// docstring of `redundancy.planning.integrate`): from q (k, n) at t = 0, whose slopes f (k, n)
// and failures (k,) are known, to `duration`, on the tableau of nodes c (s,), stage weights a
// (s, s) (the last row the 5th-order step), error weights e (s + 1,). A step's relative and
// absolute error ≤ `tolerance`; a start whose state turns bad, or whose step shrinks below
// 1e-9 × duration, is frozen (failed). With `stop`, a motion whose end of step is past a stroke
// [lower, upper] (n,) by more than `allowance`, as are its neighbours in the batch, stops.
// The accepted steps (rows, t0, h, q0 and the stage slopes (p, s + 1, n)), failed and stopped
// (k,), and, with `keep`, each batch of ends of accepted steps as (record, positions in it); None
// where `Rates` could not serve a batch.
inline py::object dormand_prince(const py::object& rates, const py::object& velocity, Array q,
                                 Array f, py::array_t<bool> failed, double duration,
                                 double tolerance, const Array& c, const Array& a, const Array& e,
                                 const Array& lower, const Array& upper, double allowance,
                                 bool stop, bool keep) {
  const auto k = q.shape(0), n = q.shape(1), s = c.shape(0);
  q = Array(q.request());  // own copies: the loop writes them
  f = Array(f.request());
  failed = py::array_t<bool>(failed.request());
  auto* dead = failed.mutable_data();
  std::vector<double> t(k, 0.0), h(k);
  std::vector<bool> past(k, false), stopped(k, false);
  for (py::ssize_t i = 0; i < k; ++i) {  // the first step's size, from q and its slope
    const auto qi = at(q, i, 1, n), fi = at(f, i, 1, n);
    const Eigen::RowVectorXd scale = tolerance * (1 + qi.array().abs());
    const double size = std::sqrt((qi.array() / scale.array()).square().mean());
    const double speed = std::sqrt((fi.array() / scale.array()).square().mean());
    h[i] = std::min(duration, 0.01 * size / std::max(speed, 1e-12));
  }
  std::vector<py::ssize_t> rows_out;
  std::vector<double> t0_out, h_out, q0_out, slopes_out;
  py::list kept;
  while (true) {
    std::vector<py::ssize_t> rows;
    for (py::ssize_t i = 0; i < k; ++i)
      if (!dead[i] && !stopped[i] && t[i] < duration) rows.push_back(i);
    if (rows.empty()) break;
    const auto r = py::ssize_t(rows.size());
    std::vector<double> step(r);
    std::vector<Matrix> slopes(s + 1, Matrix(r, n));  // the stages' q̇
    Matrix increment(r, n);
    for (py::ssize_t i = 0; i < r; ++i) {
      step[i] = std::min(h[rows[i]], duration - t[rows[i]]);
      slopes[0].row(i) = at(f, rows[i], 1, n);
    }
    std::optional<Stage> end;
    for (py::ssize_t stage = 1; stage <= s; ++stage) {  // Σ_j a_j K_j, then the stage's q̇
      Array times(r), states({r, n});
      for (py::ssize_t i = 0; i < r; ++i) {
        increment.row(i).setZero();
        for (py::ssize_t j = 0; j < stage; ++j)
          increment.row(i) += a.at(stage - 1, j) * slopes[j].row(i);
        times.mutable_data()[i] = t[rows[i]] + c.at(stage - 1) * step[i];
        at(states, i, 1, n) = at(q, rows[i], 1, n) + step[i] * increment.row(i);
      }
      end = rates_at(rates, velocity, times, states);
      if (!end) return py::none();
      for (py::ssize_t i = 0; i < r; ++i) {
        slopes[stage].row(i) = at(end->q_dot, i, 1, n);
        if (end->bad.at(i)) dead[rows[i]] = true;
      }
    }
    std::vector<py::ssize_t> accepted;
    for (py::ssize_t i = 0; i < r; ++i) {
      const auto row = rows[i];
      const Eigen::RowVectorXd q_new = at(q, row, 1, n) + step[i] * increment.row(i);
      const Eigen::RowVectorXd scale =
          tolerance * (1 + at(q, row, 1, n).array().abs().max(q_new.array().abs()));
      Eigen::RowVectorXd estimate = Eigen::RowVectorXd::Zero(n);
      for (py::ssize_t j = 0; j <= s; ++j) estimate += e.at(j) * slopes[j].row(i);
      const double error =
          std::sqrt((step[i] * estimate.array() / scale.array()).square().mean());
      const bool accept = error <= 1 && !dead[row];
      if (accept) {
        accepted.push_back(i);
        rows_out.push_back(row);
        t0_out.push_back(t[row]);
        h_out.push_back(step[i]);
        const auto q0 = at(q, row, 1, n);
        q0_out.insert(q0_out.end(), q0.data(), q0.data() + n);
        for (py::ssize_t j = 0; j <= s; ++j)
          slopes_out.insert(slopes_out.end(), slopes[j].row(i).data(),
                            slopes[j].row(i).data() + n);
        t[row] += step[i];
        at(q, row, 1, n) = q_new;
        at(f, row, 1, n) = slopes[s].row(i);
      }
      const double growth = std::clamp(0.9 * std::pow(std::max(error, 1e-10), -0.2), 0.2, 10.0);
      h[row] = step[i] * (accept ? growth : std::min(growth, 1.0));
      if (h[row] < 1e-9 * duration) dead[row] = true;
      if (accept && stop) {
        const auto x = at(end->x, i, 1, n);
        for (py::ssize_t j = 0; j < n; ++j)
          if (std::max(lower.at(j) - x(j), x(j) - upper.at(j)) > allowance) past[row] = true;
      }
    }
    if (keep && !accepted.empty()) {
      py::array_t<py::ssize_t> positions(py::ssize_t(accepted.size()));
      std::copy(accepted.begin(), accepted.end(), positions.mutable_data());
      kept.append(py::make_tuple(end->record, positions));
    }
    if (stop)
      for (py::ssize_t i = 0; i < k; ++i)
        stopped[i] = past[i] && (i == 0 || past[i - 1]) && (i == k - 1 || past[i + 1]);
  }
  const auto p = py::ssize_t(rows_out.size());
  py::array_t<py::ssize_t> rows(p);
  Array t0(p), h0(p), q0({p, n}), slopes({p, s + 1, n});
  std::copy(rows_out.begin(), rows_out.end(), rows.mutable_data());
  std::copy(t0_out.begin(), t0_out.end(), t0.mutable_data());
  std::copy(h_out.begin(), h_out.end(), h0.mutable_data());
  std::copy(q0_out.begin(), q0_out.end(), q0.mutable_data());
  std::copy(slopes_out.begin(), slopes_out.end(), slopes.mutable_data());
  py::array_t<bool> halted(k);
  std::copy(stopped.begin(), stopped.end(), halted.mutable_data());
  return py::make_tuple(rows, t0, h0, q0, slopes, failed, halted, kept);
}
