// The state in actuator coordinates (module docstring of `redundancy.resolution.state`): whether
// A is singular, J_H = J A⁻¹, M_H = A⁻ᵀ M A⁻¹, N_H = A⁻ᵀ N − M_H Ȧ q̇ and q̇ = A⁻¹ ẋ, each by
// solves with one LU factorisation of Aᵀ per state (A is never inverted; A⁻¹ b is the transposed
// solve with the same factors); for one state, which the control step shares, and over batches.
// `Evaluator` runs the pass, the built-in kinds, y, J and J_H in one call. The factors and the
// products live in storage kept across states, so that a state allocates nothing once sized.
#pragma once

#include <limits>
#include <optional>
#include <tuple>
#include <utility>
#include <variant>
#include <vector>

#include "actuators.hpp"

using Dense = Eigen::MatrixXd;
using Factor = Eigen::PartialPivLU<Dense>;

// The LU factors of Aᵀ of one state, P Aᵀ = L U (so A = Uᵀ Lᵀ P), for n = N fixed at compile
// time (Eigen::Dynamic: any n), and the solves with them, one right-hand side at a time through
// a vector kept from state to state. At these sizes Eigen's solve of a matrix, or through a
// transpose, costs more in its blocked kernels and temporaries than in the arithmetic; its
// triangular solves of one vector in place do not, and at a fixed size they are unrolled.
template <int N>
class SizedFactors {
 public:
  template <class Square>
  void compute(const Square& A) {
    lu_.compute(A.transpose());
  }

  double determinant() const { return lu_.determinant(); }

  // out = A⁻ᵀ b: P b, then L⁻¹, then U⁻¹.
  template <class In, class Out>
  void solve_transposed(const In& b, Out&& out) {
    column_ = lu_.permutationP() * b;
    lu_.matrixLU().template triangularView<Eigen::UnitLower>().solveInPlace(column_);
    lu_.matrixLU().template triangularView<Eigen::Upper>().solveInPlace(column_);
    out = column_;
  }

  // out = A⁻¹ b: U⁻ᵀ b, then L⁻ᵀ, then Pᵀ.
  template <class In, class Out>
  void solve(const In& b, Out&& out) {
    column_ = b;
    lu_.matrixLU().template triangularView<Eigen::Upper>().transpose().solveInPlace(column_);
    lu_.matrixLU().template triangularView<Eigen::UnitLower>().transpose().solveInPlace(column_);
    out = lu_.permutationP().transpose() * column_;
  }

 private:
  Eigen::PartialPivLU<Eigen::Matrix<double, N, N>> lu_;
  Eigen::Matrix<double, N, 1> column_;
};

// The LU factors of Aᵀ of one state at its n: Eigen's fixed-size kernels up to `MAX_FIXED`
// (at n = 3 a factorisation with eight solves takes a third of the dynamic kernels' time),
// its dynamic ones beyond. Chosen per `compute`, so one object serves any robot.
class Factors {
 public:
  static constexpr int MAX_FIXED = 6;

  template <class Square>
  void compute(const Square& A) {
    sized(A.rows(), [&](auto& factors) {
      factors.compute(A);
      determinant_ = factors.determinant();
    });
  }

  double determinant() const { return determinant_; }

  // out = A⁻ᵀ b.
  template <class In, class Out>
  void solve_transposed(const In& b, Out&& out) {
    current([&](auto& factors) { factors.solve_transposed(b, out); });
  }

  // out = A⁻¹ b.
  template <class In, class Out>
  void solve(const In& b, Out&& out) {
    current([&](auto& factors) { factors.solve(b, out); });
  }

 private:
  // `then` on the factors of size n, made the current ones.
  template <class Then, int N = 1>
  void sized(Eigen::Index n, Then&& then) {
    if constexpr (N > MAX_FIXED) {
      then(made<Eigen::Dynamic>());
    } else {
      if (n == N) return then(made<N>());
      sized<Then, N + 1>(n, std::forward<Then>(then));
    }
  }

  // `act` on the current factors (the alternatives in the order of `sized_`).
  template <std::size_t I = 1, class Act>
  auto current(Act&& act) -> decltype(act(std::declval<SizedFactors<Eigen::Dynamic>&>())) {
    if constexpr (I == std::variant_size_v<decltype(sized_)>) {
      return act(*std::get_if<0>(&sized_));
    } else {
      if (sized_.index() == I) return act(*std::get_if<I>(&sized_));
      return current<I + 1>(std::forward<Act>(act));
    }
  }

  template <int N>
  SizedFactors<N>& made() {
    if (!std::holds_alternative<SizedFactors<N>>(sized_))
      sized_.template emplace<SizedFactors<N>>();
    return std::get<SizedFactors<N>>(sized_);
  }

  std::variant<SizedFactors<Eigen::Dynamic>, SizedFactors<1>, SizedFactors<2>, SizedFactors<3>,
               SizedFactors<4>, SizedFactors<5>, SizedFactors<6>>
      sized_;
  double determinant_ = 0;
};

// Whether A (n, n), whose `factors` are given, is singular to working precision,
// σ_min / σ_max < tolerance or not finite: |det A| / ‖A‖_F^n bounds σ_min / σ_max from below
// (|det A| = Π σ_i ≤ σ_min σ_max^(n−1) and σ_max ≤ ‖A‖_F), so the singular values are computed
// only where that bound is not enough.
template <class Square>
bool singular(const Square& A, const Factors& factors, double tolerance) {
  if (!A.allFinite()) return true;
  const double norm = A.norm();
  double bound = tolerance;  // tolerance ‖A‖_F^n, by products (std::pow costs as much as the LU)
  for (Eigen::Index i = 0; i < A.rows(); ++i) bound *= norm;
  if (std::abs(factors.determinant()) > bound) return false;
  const Eigen::VectorXd sigma = Eigen::JacobiSVD<Dense>(A).singularValues();
  return sigma[sigma.size() - 1] / std::max(sigma[0], std::numeric_limits<double>::min()) <
         tolerance;
}

// J_H = J A⁻¹ (m, n) into `out`, row by row: J_Hᵀ = A⁻ᵀ Jᵀ.
template <class Rows, class Out>
void task_jacobian(Factors& factors, const Rows& J, Out&& out) {
  for (Eigen::Index j = 0; j < J.rows(); ++j)
    factors.solve_transposed(J.row(j).transpose(), out.row(j).transpose());
}

// One state's derivation from A (n, n) and J (m, n): the factors of Aᵀ into `factors`,
// J_H = J A⁻¹ into `out` (meaningless where A is singular), and whether A is singular.
template <class Square, class Rows, class Out>
bool derive_state(Factors& factors, const Square& A, const Rows& J, Out&& out,
                  double tolerance) {
  factors.compute(A);
  task_jacobian(factors, J, std::forward<Out>(out));
  return singular(A, factors, tolerance);
}

// M_H = A⁻ᵀ M A⁻¹ = A⁻ᵀ (A⁻ᵀ M)ᵀ for a symmetric M, symmetrised, into `out`, column by column;
// `first` and `second` hold the two solves.
template <class Square, class Out>
void inertia(Factors& factors, const Square& M, Dense& first, Dense& second, Out&& out) {
  const auto n = M.rows();
  first.resize(n, n);
  second.resize(n, n);
  for (Eigen::Index j = 0; j < n; ++j) factors.solve_transposed(M.col(j), first.col(j));
  for (Eigen::Index j = 0; j < n; ++j)
    factors.solve_transposed(first.row(j).transpose(), second.col(j));
  out = (second + second.transpose()) / 2;
}

// The k of a batch of square matrices A (k, n, n), checked against the other batches' shapes:
// each of `others` is (k, n) or (k, n, n), by its given number of dimensions.
inline std::pair<py::ssize_t, py::ssize_t> square_batch(
    const Array& A, std::initializer_list<std::tuple<const Array*, int, const char*>> others) {
  if (A.ndim() != 3 || A.shape(1) != A.shape(2))
    throw py::value_error("A must have shape (k, n, n)");
  const auto k = A.shape(0), n = A.shape(1);
  for (const auto& [other, ndim, name] : others)
    if (other->ndim() != ndim || other->shape(0) != k || other->shape(1) != n ||
        (ndim == 3 && other->shape(2) != n))
      throw py::value_error(std::string(name) + " must have shape (k, n" +
                            (ndim == 3 ? ", n)" : ")") + ", as A (k, n, n)");
  return {k, n};
}

// `value`, a ratio of singular values below which a matrix counts as (near) singular, checked to
// lie in (0, 1]: at 0 or NaN a singular matrix would pass; at 1 every matrix counts.
inline double fraction(double value, const char* name) {
  if (!(value > 0 && value <= 1))
    throw py::value_error(std::string(name) + " must lie in (0, 1]; got " +
                          std::string(py::repr(py::float_(value))));
  return value;
}

inline Eigen::Map<const Matrix> at(const Array& a, py::ssize_t i, py::ssize_t rows,
                                   py::ssize_t cols) {
  return Eigen::Map<const Matrix>(a.data() + i * rows * cols, rows, cols);
}

inline Eigen::Map<Matrix> at(Array& a, py::ssize_t i, py::ssize_t rows, py::ssize_t cols) {
  return Eigen::Map<Matrix>(a.mutable_data() + i * rows * cols, rows, cols);
}

// A copy of `values` as a numpy array: (size,) of a vector, (rows, cols) of a matrix.
inline Array array(const Eigen::VectorXd& values) {
  Array out(values.size());
  Eigen::Map<Eigen::VectorXd>(out.mutable_data(), values.size()) = values;
  return out;
}

template <class Values>
Array array(const Eigen::MatrixBase<Values>& values) {
  Array out({values.rows(), values.cols()});
  Eigen::Map<Matrix>(out.mutable_data(), values.rows(), values.cols()) = values;
  return out;
}

// J_H (k, m, n) and where A is singular (k,) bool, for A (k, n, n) and J (k, m, n); J_H is
// meaningless where A is singular.
inline py::tuple derive(const Array& A, const Array& J, double tolerance) {
  if (A.ndim() != 3 || A.shape(1) != A.shape(2) || A.shape(1) < 1 || J.ndim() != 3 ||
      J.shape(0) != A.shape(0) || J.shape(2) != A.shape(1))
    throw py::value_error("derive takes A (k, n, n) and J (k, m, n), n ≥ 1");
  fraction(tolerance, "the singular tolerance");
  const auto k = A.shape(0), n = A.shape(1), m = J.shape(1);
  Array J_H({k, m, n});
  py::array_t<bool> bad(k);
  Factors factors;
  for (py::ssize_t i = 0; i < k; ++i) {
    bad.mutable_data()[i] =
        derive_state(factors, at(A, i, n, n), at(J, i, m, n), at(J_H, i, m, n), tolerance);
  }
  return py::make_tuple(J_H, bad);
}

// M_H (k, n, n) for A and M (k, n, n).
inline Array inertias(const Array& A, const Array& M) {
  const auto [k, n] = square_batch(A, {{&M, 3, "M"}});
  Array out({k, n, n});
  Factors factors;
  Dense first, second;
  for (py::ssize_t i = 0; i < k; ++i) {
    factors.compute(at(A, i, n, n));
    inertia(factors, at(M, i, n, n), first, second, at(out, i, n, n));
  }
  return out;
}

// N_H = A⁻ᵀ N − M_H (Ȧ q̇) (k, n), for A, M_H, Ȧ (k, n, n) and N, q̇ (k, n).
inline Array biases(const Array& A, const Array& N, const Array& M_H, const Array& A_dot,
                    const Array& v) {
  const auto [k, n] = square_batch(
      A, {{&N, 2, "N"}, {&M_H, 3, "M_H"}, {&A_dot, 3, "A_dot"}, {&v, 2, "v"}});
  Array out({k, n});
  Factors factors;
  Eigen::VectorXd rate(n);
  for (py::ssize_t i = 0; i < k; ++i) {
    factors.compute(at(A, i, n, n));
    rate.noalias() = at(A_dot, i, n, n) * at(v, i, 1, n).transpose();
    auto row = at(out, i, 1, n).transpose();
    factors.solve_transposed(at(N, i, 1, n).transpose(), row);
    row.noalias() -= at(M_H, i, n, n) * rate;
  }
  return out;
}

// Whether a pivot of LU factors is exactly zero, as LAPACK's test of a singular matrix.
inline bool zero_pivot(const Factor& factor) {
  return (factor.matrixLU().diagonal().array() == 0).any();
}

// numpy's LinAlgError, "Singular matrix", raised in Python.
[[noreturn]] inline void singular_matrix() {
  PyErr_SetString(py::module_::import("numpy.linalg").attr("LinAlgError").ptr(),
                  "Singular matrix");
  throw py::error_already_set();
}

// X = A⁻¹ B for A (k, n, n) and B (k, n, p) or (k, n); numpy's LinAlgError where a pivot of A's
// factors is exactly zero, as LAPACK's.
inline Array solve(const Array& A, const Array& B) {
  const bool vectors = B.ndim() == 2;
  const auto [k, n] = square_batch(A, {});
  if ((!vectors && B.ndim() != 3) || B.shape(0) != k || B.shape(1) != n)
    throw py::value_error("B must have shape (k, n) or (k, n, p), as A (k, n, n)");
  const auto p = vectors ? 1 : B.shape(2);
  Array out(std::vector<py::ssize_t>(B.shape(), B.shape() + B.ndim()));
  Factor factor(n);
  for (py::ssize_t i = 0; i < k; ++i) {
    factor.compute(at(A, i, n, n));
    if (zero_pivot(factor)) singular_matrix();
    at(out, i, n, p) = factor.solve(at(B, i, n, p));
  }
  return out;
}

// What one state's actuator space reads: the tool's task rows and the compiled actuators.
struct Actuation {
  Eigen::Index tool;
  std::vector<Eigen::Index> rows;
  std::vector<Actuator> actuators;

  // x (n), the rows of A (n, n) and the task's y (m) and J (m, n) at one state of the pass; the
  // first actuator that cannot evaluate there, with its `Status`, or (−1, OK).
  std::pair<Eigen::Index, Status> operator()(const Frames& s, const double* q, const double* v,
                                             double* x, double* A, double* y, double* J) const {
    const auto n = s.n;
    std::pair<Eigen::Index, Status> refused{-1, OK};
    Eigen::Vector3d end;
    for (std::size_t j = 0; j < actuators.size(); ++j) {
      const auto status =
          actuate(actuators[j], s, q, v, x[j], RowOut(A + j * n, n), nullptr, end);
      if (status != OK && refused.first < 0) refused = {Eigen::Index(j), status};
    }
    for (std::size_t r = 0; r < rows.size(); ++r) {
      y[r] = s.position(tool)[rows[r]];
      Eigen::Map<Eigen::RowVectorXd>(J + r * n, n) = s.jacobian(tool).row(rows[r]);
    }
    return refused;
  }
};

// A robot's states in actuator coordinates, one call per batch: the pass, x and A of the
// built-in kinds (all the robot's actuators), y and J, J_H, and where A is singular or q not
// finite.
class Evaluator {
 public:
  Evaluator(const Pass& pass, Eigen::Index tool, std::vector<Eigen::Index> rows,
            const py::array_t<int>& kinds, const py::array_t<Eigen::Index>& slots,
            const Array& numbers, double tolerance)
      : pass_(pass),
        actuation_{tool, std::move(rows), declared(kinds, slots, numbers, pass.size(), pass.n())},
        tolerance_(fraction(tolerance, "the singular tolerance")) {
    if (tool < 0 || tool >= pass_.size() ||
        Eigen::Index(actuation_.actuators.size()) != pass_.n() ||
        std::any_of(actuation_.rows.begin(), actuation_.rows.end(),
                    [](auto r) { return r < 0 || r > 2; }))
      throw py::value_error("an evaluator takes the tool's slot, its task rows and n actuators");
  }

  // At q (k, n) or (n,) and v like q or None: (q, v) as batches, positions, jacobians, angular,
  // velocities, rates (`Pass.kinematics`), x, A, y, J, J_H, where the state is bad (k,) bool
  // (A singular, q not finite, or a kind refused it: there x, A and J_H are NaN), and None or
  // the first (state, actuator, status) a kind refused. None where q or v is not a float64 array
  // of that shape (finite too, if `finite`): Python then checks them.
  py::object evaluate(const py::object& q, const py::object& v, bool finite) {
    return evaluate(q, v, finite, nullptr);
  }

  // `evaluate`, keeping, where `kept` is given, the factors of each state's Aᵀ there (grown to
  // the batch) for the caller's solves: state i's at (*kept)[i] where it is not bad. Without
  // it, one set of factors serves each state in turn.
  py::object evaluate(const py::object& q, const py::object& v, bool finite,
                      std::vector<Factors>* kept) {
    const auto n = pass_.n();
    const auto qa = batch(q, n, finite);
    if (!qa) return py::none();
    const auto k = qa->shape(0);
    std::optional<Array> va;
    if (!v.is_none()) {
      va = batch(v, n, finite);
      if (!va || va->shape(0) != k) return py::none();
    }
    auto [positions, linear, angular, velocities, rates] = pass_.outputs(k, va.has_value());
    const auto m = Eigen::Index(actuation_.rows.size());
    Array x({k, n}), A({k, n, n}), y({k, m}), J({k, m, n}), J_H({k, m, n});
    py::array_t<bool> bad(k);
    py::object refused = py::none();
    if (kept && kept->size() < std::size_t(k)) kept->resize(std::size_t(k));
    for (py::ssize_t i = 0; i < k; ++i) {
      const double* qi = qa->data() + i * n;
      const double* vi = va ? va->data() + i * n : nullptr;
      const Frames s = pass_.write(qi, vi, i, positions, linear, angular, velocities, rates);
      auto& factors = kept ? (*kept)[std::size_t(i)] : factors_;
      const auto [actuator, status] =
          derived(s, qi, vi, x.mutable_data() + i * n, A.mutable_data() + i * n * n,
                  y.mutable_data() + i * m, J.mutable_data() + i * m * n,
                  J_H.mutable_data() + i * m * n, factors, bad.mutable_data()[i]);
      if (status != OK && refused.is_none()) refused = py::make_tuple(i, actuator, int(status));
    }
    return py::make_tuple(*qa, Pass::maybe(va), positions, linear, angular,
                          Pass::maybe(velocities), Pass::maybe(rates), x, A, y, J, J_H, bad,
                          refused);
  }

  // x (k, n), y (k, m), J_H (k, m·n) and where the state is bad (k,) at q (k, n), the factors of
  // each state's Aᵀ in `kept` (grown to the batch): what a law reads at a state of its
  // integration, without the pass's arrays, which the stages between samples need not keep.
  void derive(const Matrix& q, Matrix& x, Matrix& y, Matrix& J_H, std::vector<bool>& bad,
              std::vector<Factors>& kept) {
    const auto k = q.rows(), n = pass_.n(), m = this->m();
    x.resize(k, n);
    y.resize(k, m);
    J_H.resize(k, m * n);
    bad.assign(std::size_t(k), false);
    A_.resize(n, n);
    J_.resize(m, n);
    if (kept.size() < std::size_t(k)) kept.resize(std::size_t(k));
    for (Eigen::Index i = 0; i < k; ++i) {
      const double* qi = q.row(i).data();
      pass_.at(qi, nullptr);
      bool flag = false;
      derived(pass_.frames(), qi, nullptr, x.row(i).data(), A_.data(), y.row(i).data(), J_.data(),
              J_H.row(i).data(), kept[std::size_t(i)], flag);
      bad[std::size_t(i)] = flag;
    }
  }

  // The pass the states are evaluated on (what a law's M(q) is read from, after `evaluate`).
  Pass& pass() { return pass_; }

  // The task's coordinates m.
  Eigen::Index m() const { return Eigen::Index(actuation_.rows.size()); }

  // One state of the pass `s` at q (n) and v (n) or null: x (n), A (n, n), y (m) and J (m, n),
  // row-major, and, unless a kind refused the state, the factors of Aᵀ and J_H (m, n); `bad`
  // where A is singular, q not finite or a kind refused (there x, A and J_H are NaN). Returns
  // the refusing actuator with its `Status`, or (−1, OK).
  std::pair<Eigen::Index, Status> derived(const Frames& s, const double* q, const double* v,
                                          double* x, double* A, double* y, double* J,
                                          double* J_H, Factors& factors, bool& bad) {
    const auto n = pass_.n(), m = this->m();
    const auto refused = actuation_(s, q, v, x, A, y, J);
    if (refused.second != OK) {  // bad, as a singular A: frozen by the integrators
      bad = true;
      constexpr double nan = std::numeric_limits<double>::quiet_NaN();
      Eigen::Map<Eigen::VectorXd>(x, n).setConstant(nan);
      Eigen::Map<Matrix>(A, n, n).setConstant(nan);
      Eigen::Map<Matrix>(J_H, m, n).setConstant(nan);
      return refused;
    }
    bad = derive_state(factors, ConstMatrix(A, n, n), ConstMatrix(J, m, n),
                       Eigen::Map<Matrix>(J_H, m, n), tolerance_) ||
          !Vector(q, n).allFinite();
    return refused;
  }

 private:
  // `value` as a (k, n) batch when it is a float64 array (n,) or (k, n), C-contiguous, and
  // finite where asked; else nothing.
  static std::optional<Array> batch(const py::object& value, Eigen::Index n, bool finite) {
    if (!py::isinstance<Array>(value)) return std::nullopt;
    auto array = py::reinterpret_borrow<Array>(value);
    if (array.ndim() < 1 || array.ndim() > 2 || array.shape(array.ndim() - 1) != n)
      return std::nullopt;
    if (finite && !Vector(array.data(), array.size()).allFinite()) return std::nullopt;
    if (array.ndim() == 1) return Array(array.reshape({py::ssize_t(1), py::ssize_t(n)}));
    return array;
  }

  Pass pass_;
  Actuation actuation_;
  Factors factors_;  // each state's in turn, where the caller keeps none
  Matrix A_, J_;  // one state's, for `derive`
  double tolerance_;
};
