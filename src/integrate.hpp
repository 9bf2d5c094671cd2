// The adaptive integration of a law along a segment (`redundancy.planning.integrate`): the
// Dormand-Prince 5(4) loop over a batch of starts, each with its own step size, and the compiled
// right-hand side q̇(t, q) of a built-in law on built-in kinds (`Rates`).
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "rule.hpp"

using Flags = py::array_t<bool, py::array::c_style | py::array::forcecast>;  // a batch's (k,)

// What a right-hand side gives at r states: q̇ (r, n), the strokes x (r, n), where the state is
// bad (r,) (A singular or not finite, or a kind refused it: there q̇ = 0), where asked its record
// of the states (for the ends of accepted steps, where the integration samples them), and where
// a built-in weighted law damped its solve (r,) (J_H singular to its ratio; empty where the law
// does not say: a held law's, or one in Python).
struct Stage {
  Matrix q_dot, x;
  std::vector<bool> bad;
  py::object record;
  std::vector<bool> damped;
};

// The task velocity ẏ (r, m) at times t (r,) where the tool is at y (r, m): `velocity` is ẏ
// itself, (m,), where it is constant along the path; (y_d(0), ẏ_d, K) on such a path in closed
// loop, ẏ = ẏ_d + K (y_d(0) + ẏ_d t − y); or a Python callable (t, y) → ẏ (r, m).
inline Matrix task_velocity(const py::object& velocity, const Eigen::VectorXd& t, const Matrix& y) {
  const auto r = y.rows(), m = y.cols();
  const auto constant = [m](const py::handle& value) {
    const auto out = value.cast<Array>();
    if (out.ndim() != 1 || out.shape(0) != m)
      throw py::value_error("a constant ẏ_d and its path's start must have shape (m,)");
    return Eigen::RowVectorXd(at(out, 0, 1, m));
  };
  if (py::isinstance<Array>(velocity)) return constant(velocity).replicate(r, 1);
  if (py::isinstance<py::tuple>(velocity)) {
    const auto loop = velocity.cast<py::tuple>();
    if (loop.size() != 3) throw py::value_error("a closed loop is (y_d(0), ẏ_d, K)");
    const auto start = constant(loop[0]), steady = constant(loop[1]);
    const double gain = loop[2].cast<double>();
    Matrix out(r, m);
    for (Eigen::Index i = 0; i < r; ++i)
      out.row(i) = steady + gain * (start + t(i) * steady - y.row(i));
    return out;
  }
  const Array out = velocity(array(t), array(y));
  if (out.ndim() != 2 || out.shape(0) != r || out.shape(1) != m)
    throw py::value_error("the task velocity must have shape (r, m)");
  return at(out, 0, r, m);
}

// q̇(t, q) = A⁻¹ ẋ of a built-in law at states evaluated by the compiled `Evaluator`, for the
// task velocity given by `velocity` (`task_velocity`: constant, with its closed loop on a
// steady path, or one call of Python per batch): a weighted pseudoinverse (`Rule`), or a held
// law (`Held`) whose held actuators' rates `held(t, x_h)` → (r, h) Python gives, once per
// batch, from the times and their strokes. Where a record is asked for, it is (the evaluator's
// tuple, ẋ, q̇), which is also what a call from Python returns (`Law.evaluated`: the starts,
// the samples between steps and on a grid); without one, the states are derived without the
// pass's arrays (`Evaluator::derive`), alike to the last bit. A state a kind refused is bad, as
// where A is singular. None where the core cannot serve the states (Python evaluates them again
// and raises its error).
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

  std::optional<Stage> operator()(const Eigen::VectorXd& t, const Matrix& q,
                                  const py::object& velocity, bool record) {
    auto& evaluator = evaluator_.cast<Evaluator&>();
    const auto r = q.rows(), n = q.cols();
    if (n != evaluator.pass().n()) return std::nullopt;  // Python says what is wrong
    Stage out{Matrix::Zero(r, n), Matrix(), {}, py::none()};
    py::object evaluated = py::none();
    if (record) {
      evaluated = evaluator.evaluate(array(q), py::none(), false, &factors_);
      if (evaluated.is_none()) return std::nullopt;
      const auto found = evaluated.cast<py::tuple>();
      const auto x = found[7].cast<Array>(), y = found[9].cast<Array>();
      const auto J_H = found[11].cast<Array>();
      const auto bad = found[12].cast<py::array_t<bool>>();
      out.x = at(x, 0, r, n);
      y_ = at(y, 0, r, y.shape(1));
      J_H_ = at(J_H, 0, r, J_H.shape(1) * n);
      out.bad.assign(bad.data(), bad.data() + r);
    } else {
      evaluator.derive(q, out.x, y_, J_H_, out.bad, factors_);
    }
    const auto m = y_.cols();
    const Matrix y_dot = task_velocity(velocity, t, y_);
    std::optional<Array> targets;  // a held law's rates (r, h)
    if (held_) targets = held_rates(t, out.x);
    const auto h = targets ? targets->shape(1) : 0;
    Matrix x_dot;  // ẋ, which only the record reads
    if (record) x_dot.setZero(r, n);
    if (rule_) out.damped.assign(std::size_t(r), false);
    for (Eigen::Index i = 0; i < r; ++i) {
      if (out.bad[std::size_t(i)]) continue;
      auto& factors = factors_[std::size_t(i)];  // of Aᵀ, as the evaluation derived them
      const auto y_dot_i = y_dot.row(i).transpose();
      const ConstMatrix J_H_i(J_H_.row(i).data(), m, n);
      const auto* solved =
          held_ ? (*held_)(J_H_i, y_dot_i, at(*targets, i, 1, h).transpose())
                : (*rule_)(evaluator.pass(), q.row(i).data(), out.x.row(i).transpose(), factors,
                           J_H_i, y_dot_i);
      if (!solved) return std::nullopt;
      if (rule_) out.damped[std::size_t(i)] = rule_->damped();
      auto vi = out.q_dot.row(i).transpose();
      factors.solve(*solved, vi);  // q̇ = A⁻¹ ẋ
      if (!vi.allFinite()) {
        out.bad[std::size_t(i)] = true;
        vi.setZero();
        continue;
      }
      if (record) x_dot.row(i) = solved->transpose();
    }
    if (record) {  // its flags as the law found them, q̇ not finite included
      auto flags = evaluated.cast<py::tuple>()[12].cast<py::array_t<bool>>();
      std::copy(out.bad.begin(), out.bad.end(), flags.mutable_data());
      out.record = py::make_tuple(evaluated, array(x_dot), array(out.q_dot));
    }
    return out;
  }

 private:
  // The held actuators' rates (r, h) at times t (r,), from their strokes among x (r, n).
  Array held_rates(const Eigen::VectorXd& t, const Matrix& x) const {
    const auto& rows = held_->rows();
    const auto r = x.rows(), h = Eigen::Index(rows.size());
    Matrix strokes(r, h);
    for (Eigen::Index j = 0; j < h; ++j) strokes.col(j) = x.col(rows[std::size_t(j)]);
    const Array out = rates_(array(t), array(strokes));
    if (out.ndim() != 2 || out.shape(0) != r || out.shape(1) != h)
      throw py::value_error("the held actuators' rates must have shape (r, h)");
    return out;
  }

  py::object evaluator_;
  std::optional<Rule> rule_;
  std::optional<Held> held_;
  py::object rates_;  // a held law's rates, a Python callable (t, x_h) → (r, h)
  std::vector<Factors> factors_;  // each state's, kept by the evaluation for the solves here
  Matrix y_, J_H_;  // the states' task points and J_H (r, m·n)
};

// A right-hand side at r states: `Rates` in C++ (with its record where `record`), or a Python
// callable (t, q) → (record, q̇, bad, x).
inline std::optional<Stage> rates_at(const py::object& rates, const py::object& velocity,
                                     const Eigen::VectorXd& t, const Matrix& q, bool record) {
  if (py::isinstance<Rates>(rates)) return rates.cast<Rates&>()(t, q, velocity, record);
  const auto out = rates(array(t), array(q)).cast<py::tuple>();
  const auto q_dot = out[1].cast<Array>(), x = out[3].cast<Array>();
  const auto bad = out[2].cast<Flags>();
  const auto r = q.rows(), n = q.cols();
  const auto batch = [r, n](const Array& a) {
    return a.ndim() == 2 && a.shape(0) == r && a.shape(1) == n;
  };
  if (!batch(q_dot) || !batch(x) || bad.ndim() != 1 || bad.shape(0) != r)
    throw py::value_error("a right-hand side gives q̇ and x (r, n), and bad (r,)");
  return Stage{at(q_dot, 0, r, n), at(x, 0, r, n),
               std::vector<bool>(bad.data(), bad.data() + r), out[0]};
}

// A copy of the C-contiguous array `a`, of its shape and type: from its data, not from its
// buffer, whose format string numpy would parse in Python (15 µs of each call of the loop).
template <class Contiguous>
Contiguous owned(const Contiguous& a) {
  Contiguous out(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
  std::copy_n(a.data(), a.size(), out.mutable_data());
  return out;
}

// Whether the array `a` has exactly the shape `shape`.
inline bool shaped(const py::array& a, std::initializer_list<py::ssize_t> shape) {
  return a.ndim() == py::ssize_t(shape.size()) &&
         std::equal(shape.begin(), shape.end(), a.shape());
}

// Dormand-Prince 5(4) with error control on q, every start with its own step size (the module
// docstring of `redundancy.planning.integrate`): from q (k, n) at t = 0, whose slopes f (k, n)
// and failures (k,) are known, to `duration`, on the tableau of nodes c (s,), stage weights a
// (s, s) (the last row the 5th-order step), error weights e (s + 1,). A step's relative and
// absolute error ≤ `tolerance`; a start whose state turns bad, whose step shrinks below
// 1e-9 × duration, that has tried `max_steps` steps (accepted or not) short of the end, or whose
// last `max_singular` accepted steps all ended where the law damped its solve (J_H singular: the
// path has left the arm's reach, and the law crawls along its edge), is frozen (failed): steps a
// millionth of the duration would otherwise run on for a million steps, and keep them all. No step
// crosses one of the sorted times `breaks` in (0, duration), where the path's ẏ_d is not smooth
// (a speed profile's ramp ends, a polyline's corners): a step that straddles one is as accurate
// as its order there, not as the error estimate says. Times closer than `same_time` × duration
// are one (the path's `SAME_TIME`): a break a step reached to rounding is passed. Where ẏ_d
// jumps there, a step that ends on a break reads its stages at its end (c = 1: Dormand-Prince
// has two) that much before it (the piece it integrated), and the next step's first slope is the
// law's that much after it (the next piece), one more evaluation per break. With `stop`, a
// motion whose end of step is past a stroke [lower, upper] (n,) by more than `allowance`, as are
// its neighbours in the batch, stops. A start whose error estimate is not finite (a Python
// right-hand side's q̇ NaN) is frozen too.
// The accepted steps (rows, t0, h, q0 and the stage slopes (p, s + 1, n)), failed and stopped
// (k,), and, with `keep`, each batch of ends of accepted steps as (record, positions in it); None
// where `Rates` could not serve a batch.
inline py::object dormand_prince(const py::object& rates, const py::object& velocity, Array q,
                                 Array f, Flags failed, double duration, const Array& breaks,
                                 double same_time, double tolerance, const Array& c,
                                 const Array& a, const Array& e, const Array& lower,
                                 const Array& upper, double allowance, bool stop, bool keep,
                                 long max_steps, long max_singular) {
  if (q.ndim() != 2) throw py::value_error("the starts q must have shape (k, n)");
  const auto k = q.shape(0), n = q.shape(1), s = c.shape(0);
  if (!shaped(f, {k, n}) || !shaped(failed, {k}) || !shaped(lower, {n}) || !shaped(upper, {n}))
    throw py::value_error("the slopes f (k, n), failed (k,) and the strokes (n,) must fit q");
  if (s < 1 || !shaped(c, {s}) || !shaped(a, {s, s}) || !shaped(e, {s + 1}))
    throw py::value_error("the tableau is c (s,), a (s, s) and e (s + 1,), s ≥ 1");
  if (!(duration > 0 && std::isfinite(duration) && tolerance > 0 && std::isfinite(tolerance)))
    throw py::value_error("the duration and the tolerance must be finite and > 0");
  if (max_steps < 1 || max_singular < 1)
    throw py::value_error("max_steps and max_singular must be at least 1");
  if (breaks.ndim() != 1 || !std::is_sorted(breaks.data(), breaks.data() + breaks.size()))
    throw py::value_error("the breaks must be sorted times (b,)");
  if (!(same_time > 0 && same_time < 1))
    throw py::value_error("same_time must lie in (0, 1): a fraction of the duration");
  const double rounding = same_time * duration;  // times closer are one
  // the end of a step from t: the first break past t (one reached, to rounding, is passed),
  // else the duration
  const auto reach = [&](double from) {
    const double* next = std::upper_bound(breaks.data(), breaks.data() + breaks.size(),
                                          from + rounding);
    return next == breaks.data() + breaks.size() ? duration : std::min(*next, duration);
  };
  q = owned(q);  // the loop writes them
  f = owned(f);
  failed = owned(failed);
  auto* dead = failed.mutable_data();
  std::vector<double> t(k, 0.0), h(k);
  std::vector<long> tried(k, 0), singular(k, 0);  // steps tried; accepted, in a row, damped
  std::vector<bool> past(k, false), stopped(k, false), broken(k, false);
  for (py::ssize_t i = 0; i < k; ++i) {  // the first step's size, from q and its slope
    const auto qi = at(q, i, 1, n), fi = at(f, i, 1, n);
    const Eigen::RowVectorXd scale = tolerance * (1 + qi.array().abs());
    const double size = std::sqrt((qi.array() / scale.array()).square().mean());
    const double speed = std::sqrt((fi.array() / scale.array()).square().mean());
    h[i] = std::min(duration, 0.01 * size / std::max(speed, 1e-12));
    // at q = 0 that size is 0: start at 1e-6 of the duration, which the control then grows
    if (!(h[i] >= 1e-6 * duration)) h[i] = 1e-6 * duration;
  }
  std::vector<py::ssize_t> rows_out;
  std::vector<double> t0_out, h_out, q0_out, slopes_out;
  py::list kept;
  while (true) {
    std::vector<py::ssize_t> rows;
    for (py::ssize_t i = 0; i < k; ++i)
      if (!dead[i] && !stopped[i] && t[i] < duration) rows.push_back(i);
    if (rows.empty()) break;
    std::vector<py::ssize_t> fresh;  // at a break they reached: their slope there, afresh
    for (const auto row : rows)
      if (broken[row]) fresh.push_back(row);
    if (!fresh.empty()) {
      Eigen::VectorXd when(py::ssize_t(fresh.size()));
      Matrix where(py::ssize_t(fresh.size()), n);
      for (std::size_t i = 0; i < fresh.size(); ++i) {
        when(py::ssize_t(i)) = t[fresh[i]] + rounding;  // ẏ_d of the piece after it
        where.row(py::ssize_t(i)) = at(q, fresh[i], 1, n);
      }
      const auto slope = rates_at(rates, velocity, when, where, false);
      if (!slope) return py::none();
      for (std::size_t i = 0; i < fresh.size(); ++i) {
        at(f, fresh[i], 1, n) = slope->q_dot.row(py::ssize_t(i));
        if (slope->bad[i]) dead[fresh[i]] = true;
        broken[fresh[i]] = false;
      }
      rows.erase(std::remove_if(rows.begin(), rows.end(), [&](auto row) { return dead[row]; }),
                 rows.end());
      if (rows.empty()) continue;
    }
    const auto r = py::ssize_t(rows.size());
    std::vector<double> step(r), ends(r);
    std::vector<bool> on_break(r);  // the step ends on a break
    std::vector<Matrix> slopes(s + 1, Matrix(r, n));  // the stages' q̇
    Matrix increment(r, n), states(r, n);
    Eigen::VectorXd times(r);
    for (py::ssize_t i = 0; i < r; ++i) {
      ends[i] = reach(t[rows[i]]);
      step[i] = std::min(h[rows[i]], ends[i] - t[rows[i]]);
      // a step that would stop short of a break or the end by a time that is one with it goes
      // to it: a step of an ulp would follow, its sample an ulp after the last (ẍ by
      // differences of ẋ then divided by that ulp)
      if (ends[i] - t[rows[i]] - step[i] <= rounding) step[i] = ends[i] - t[rows[i]];
      on_break[i] = step[i] == ends[i] - t[rows[i]] && ends[i] < duration;
      slopes[0].row(i) = at(f, rows[i], 1, n);
    }
    std::optional<Stage> end;
    for (py::ssize_t stage = 1; stage <= s; ++stage) {  // Σ_j a_j K_j, then the stage's q̇
      for (py::ssize_t i = 0; i < r; ++i) {
        increment.row(i).setZero();
        for (py::ssize_t j = 0; j < stage; ++j)
          increment.row(i) += a.at(stage - 1, j) * slopes[j].row(i);
        times(i) = t[rows[i]] + c.at(stage - 1) * step[i];
        // a stage at the end of a step that ends on a break (the tableau has two): ẏ_d of the
        // piece before it
        if (on_break[i] && c.at(stage - 1) >= 1) times(i) -= rounding;
        states.row(i) = at(q, rows[i], 1, n) + step[i] * increment.row(i);
      }
      // the last stage is the step's end: recorded where the ends are kept (a sample each)
      end = rates_at(rates, velocity, times, states, keep && stage == s);
      if (!end) return py::none();
      slopes[stage] = end->q_dot;
      for (py::ssize_t i = 0; i < r; ++i)
        if (end->bad[std::size_t(i)]) dead[rows[i]] = true;
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
        broken[row] = on_break[i];
        // a step to a break or to the end lands on it (t + (end − t) may fall an ulp short)
        t[row] = step[i] == ends[i] - t[row] ? ends[i] : t[row] + step[i];
        at(q, row, 1, n) = q_new;
        at(f, row, 1, n) = slopes[s].row(i);
        const bool damped = !end->damped.empty() && end->damped[std::size_t(i)];
        singular[row] = damped ? singular[row] + 1 : 0;
        if (singular[row] >= max_singular && t[row] < duration) dead[row] = true;
      }
      const double growth = std::clamp(0.9 * std::pow(std::max(error, 1e-10), -0.2), 0.2, 10.0);
      const double proposed = step[i] * (accept ? growth : std::min(growth, 1.0));
      // a step cut short by a break says nothing against the size it was cut from
      h[row] = accept && step[i] < h[row] ? std::max(h[row], proposed) : proposed;
      if (!(h[row] >= 1e-9 * duration)) dead[row] = true;  // NaN too: an error not finite
      if (++tried[row] >= max_steps && t[row] < duration) dead[row] = true;
      if (accept && stop) {
        const auto x = end->x.row(i);
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

// The least and greatest stroke of every actuator over each of k motions after its start (the
// start itself excluded), (k, n) each, for samples at times t (k, T) of x and ẋ (k, T, n): at
// the samples and, between two, at the interior extrema of the cubic Hermite interpolant
// through x and ẋ at both ends, p(s) = a s³ + b s² + d₀ s + x₀ over s ∈ [0, 1] with d = h ẋ,
// a = 2 (x₀ − x₁) + d₀ + d₁ and b = 3 (x₁ − x₀) − 2 d₀ − d₁, where p′ = 3 a s² + 2 b s + d₀
// vanishes: s = (−b ± √(b² − 3 a d₀)) / 3a, or −d₀ / 2b where p is (nearly) quadratic. A
// repeated last sample (h = 0) adds nothing; motions of their start alone (T = 1: frozen there)
// have none after it, +∞ and −∞.
inline py::tuple stroke_extremes(const Array& t, const Array& x, const Array& x_dot) {
  if (t.ndim() != 2 || t.shape(1) < 1 || x.ndim() != 3 ||
      !shaped(x, {t.shape(0), t.shape(1), x.shape(2)}) ||
      !shaped(x_dot, {x.shape(0), x.shape(1), x.shape(2)}))
    throw py::value_error("stroke_extremes takes t (k, T), x and x_dot (k, T, n), T ≥ 1");
  const auto k = x.shape(0), T = x.shape(1), n = x.shape(2);
  Array lowest({k, n}), highest({k, n});
  auto* low = lowest.mutable_data();
  auto* high = highest.mutable_data();
  const auto* times = t.data();
  const auto* strokes = x.data();
  const auto* rates = x_dot.data();
  for (py::ssize_t i = 0; i < k; ++i) {
    for (py::ssize_t j = 0; j < n; ++j) {
      const auto sample = [&](py::ssize_t u) { return strokes[(i * T + u) * n + j]; };
      double least = INFINITY, most = -INFINITY;
      for (py::ssize_t u = 1; u < T; ++u) {  // a NaN sample stays, as numpy's minimum keeps it
        const double value = sample(u);
        if (std::isnan(least) || std::isnan(value)) {
          least = most = std::isnan(least) ? least : value;
          continue;
        }
        least = std::min(least, value);
        most = std::max(most, value);
      }
      for (py::ssize_t u = 0; u + 1 < T; ++u) {
        const double h = times[i * T + u + 1] - times[i * T + u];
        const double x0 = sample(u), x1 = sample(u + 1);
        const double d0 = h * rates[(i * T + u) * n + j], d1 = h * rates[(i * T + u + 1) * n + j];
        const double a = 2 * (x0 - x1) + d0 + d1, b = 3 * (x1 - x0) - 2 * d0 - d1;
        const double discriminant = b * b - 3 * a * d0;
        if (!(discriminant >= 0)) continue;
        const double root = std::sqrt(discriminant);
        const bool cubic = std::abs(a) > 1e-12 * (std::abs(b) + std::abs(d0));
        const double candidates[2] = {cubic ? (-b + root) / (3 * a) : -d0 / (2 * b),
                                      cubic ? (-b - root) / (3 * a) : NAN};
        for (const double s : candidates) {
          if (!(s > 0 && s < 1)) continue;
          const double value = ((a * s + b) * s + d0) * s + x0;
          least = std::min(least, value);
          most = std::max(most, value);
        }
      }
      low[i * n + j] = least;
      high[i * n + j] = most;
    }
  }
  return py::make_tuple(lowest, highest);
}
