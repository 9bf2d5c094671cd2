// redundancy._core: the one Pinocchio pass over a batch of states, a cylinder's length with its
// rows of A and Ȧ, and the resolution laws' kernel, compiled.
//
// A `Pass` holds a copy of the robot's Pinocchio model (handed over as Pinocchio's own text
// serialization, so that mimic joints, locked joints and added frames arrive exactly as Python
// built them), its own Data, and the tracked frames. Each call loops over k states in C++ and
// writes numpy arrays, batch axis first.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Dense>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace py = pybind11;
using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;
using RowBlock = Eigen::Map<Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::RowMajor>>;
using Vector = Eigen::Map<const Eigen::VectorXd>;
constexpr auto WORLD = pinocchio::LOCAL_WORLD_ALIGNED;

class Pass {
 public:
  Pass(std::string model, std::vector<pinocchio::FrameIndex> frames)
      : text_(std::move(model)), frames_(std::move(frames)) {
    model_.loadFromString(text_);
    // Pinocchio 4.1's serialization does not keep a mimic joint's extended sizes (it reads them
    // back as −1, and a Data built from them is broken): each is rebuilt from what was kept.
    for (const auto j : model_.mimicking_joints) {
      const auto loaded = boost::get<pinocchio::JointModelMimic>(model_.joints[j].toVariant());
      pinocchio::JointModelMimic mimic(loaded.jmodel(), loaded.scaling(), loaded.offset());
      mimic.setIndexes(loaded.id(), loaded.idx_q(), loaded.idx_v(), loaded.idx_vExtended());
      mimic.setMimicIndexes(loaded.jmodel().id(), loaded.idx_q(), loaded.idx_v(),
                            loaded.jmodel().idx_vExtended());
      model_.joints[j] = mimic;
    }
    data_ = pinocchio::Data(model_);
    six_ = pinocchio::Data::Matrix6x::Zero(6, model_.nv);
    six_rate_ = six_;
    for (auto frame : frames_)
      if (frame >= model_.frames.size())
        throw py::value_error("frame " + std::to_string(frame) + " is not in the model");
  }

  using State = std::pair<std::string, std::vector<pinocchio::FrameIndex>>;
  State state() const { return {text_, frames_}; }

  // Positions (k, F, 3), linear and angular world-aligned Jacobians (k, F, 3, n) of the tracked
  // frames at q (k, n); with v (k, n) also their velocities (k, F, 3) and linear Jacobian rates
  // (k, F, 3, n), from Pinocchio's time variation (mimic joints included).
  py::tuple kinematics(const Array& q, const std::optional<Array>& v) {
    const auto k = batch(q, "q");
    if (v) same_batch(*v, k, "v");
    const auto F = static_cast<py::ssize_t>(frames_.size()), n = py::ssize_t(model_.nv);
    Array positions({k, F, py::ssize_t(3)}), linear({k, F, py::ssize_t(3), n}),
        angular({k, F, py::ssize_t(3), n});
    py::object velocities = py::none(), rates = py::none();
    double *p = positions.mutable_data(), *jl = linear.mutable_data(),
           *ja = angular.mutable_data(), *pv = nullptr, *jr = nullptr;
    if (v) {
      Array velocity({k, F, py::ssize_t(3)}), rate({k, F, py::ssize_t(3), n});
      pv = velocity.mutable_data();
      jr = rate.mutable_data();
      velocities = velocity;
      rates = rate;
    }
    for (py::ssize_t i = 0; i < k; ++i) {
      const Vector qi(q.data() + i * n, n);
      if (v) {
        const Vector vi(v->data() + i * n, n);
        pinocchio::computeJointJacobiansTimeVariation(model_, data_, qi, vi);
      } else {
        pinocchio::computeJointJacobians(model_, data_, qi);
      }
      for (auto frame : frames_) {
        const auto& placement = pinocchio::updateFramePlacement(model_, data_, frame);
        Eigen::Map<Eigen::Vector3d>{p} = placement.translation();
        six_.setZero();
        pinocchio::getFrameJacobian(model_, data_, frame, WORLD, six_);
        RowBlock(jl, 3, n) = six_.topRows<3>();
        RowBlock(ja, 3, n) = six_.bottomRows<3>();
        if (v) {
          six_rate_.setZero();
          pinocchio::getFrameJacobianTimeVariation(model_, data_, frame, WORLD, six_rate_);
          RowBlock(jr, 3, n) = six_rate_.topRows<3>();
          Eigen::Map<Eigen::Vector3d>{pv} = six_.topRows<3>() * Vector(v->data() + i * n, n);
          pv += 3;
          jr += 3 * n;
        }
        p += 3;
        jl += 3 * n;
        ja += 3 * n;
      }
    }
    return py::make_tuple(positions, linear, angular, velocities, rates);
  }

  // M(q) (k, n, n) by CRBA, both triangles filled.
  Array mass_matrices(const Array& q) {
    const auto k = batch(q, "q");
    const auto n = py::ssize_t(model_.nv);
    Array out({k, n, n});
    for (py::ssize_t i = 0; i < k; ++i) {
      pinocchio::crba(model_, data_, Vector(q.data() + i * n, n));
      data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose();
      Eigen::Map<Eigen::MatrixXd>(out.mutable_data() + i * n * n, n, n) = data_.M;
    }
    return out;
  }

  // N(q, v) = V(q, v) + G(q) (k, n) by RNEA.
  Array nonlinear(const Array& q, const Array& v) {
    const auto k = batch(q, "q");
    same_batch(v, k, "v");
    const auto n = py::ssize_t(model_.nv);
    Array out({k, n});
    for (py::ssize_t i = 0; i < k; ++i) {
      Eigen::Map<Eigen::VectorXd>(out.mutable_data() + i * n, n) = pinocchio::nonLinearEffects(
          model_, data_, Vector(q.data() + i * n, n), Vector(v.data() + i * n, n));
    }
    return out;
  }

 private:
  py::ssize_t batch(const Array& a, const char* name) const {
    if (a.ndim() != 2 || a.shape(1) != model_.nv)
      throw py::value_error(std::string(name) + " must have shape (k, " +
                            std::to_string(model_.nv) + ")");
    return a.shape(0);
  }
  void same_batch(const Array& a, py::ssize_t k, const char* name) const {
    if (batch(a, name) != k)
      throw py::value_error(std::string(name) + " must have as many rows as q");
  }

  std::string text_;  // the serialized model: what a copy of the pass is rebuilt from
  pinocchio::Model model_;
  pinocchio::Data data_;
  std::vector<pinocchio::FrameIndex> frames_;
  pinocchio::Data::Matrix6x six_, six_rate_;
};

using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstMatrix = Eigen::Map<const Matrix>;
using Row = Eigen::Map<Eigen::RowVectorXd>;

// A cylinder's length between its two ends: of the spans d (k, c, 3) of c cylinders and their
// Jacobians ∂d/∂q (k, c, 3, n), the lengths x = |d| (k, c) and the rows of A, uᵀ ∂d/∂q
// (k, c, n), u = d / x; with the rates ḋ (k, c, 3) and d(∂d/∂q)/dt (k, c, 3, n) also the rows
// of Ȧ, u̇ᵀ ∂d/∂q + uᵀ d(∂d/∂q)/dt (k, c, n), u̇ = (I − u uᵀ) ḋ / x. A zero length gives NaN
// rows (the caller refuses it, naming the cylinder).
py::tuple span(const Array& d, const Array& jacobian, const std::optional<Array>& velocity,
               const std::optional<Array>& rate) {
  if (d.ndim() != 3 || d.shape(2) != 3 || jacobian.ndim() != 4 ||
      jacobian.shape(0) != d.shape(0) || jacobian.shape(1) != d.shape(1) ||
      jacobian.shape(2) != 3)
    throw py::value_error("span takes d (k, c, 3) and its Jacobian (k, c, 3, n)");
  const auto k = d.shape(0), c = d.shape(1), n = jacobian.shape(3);
  if (velocity.has_value() != rate.has_value() ||
      (velocity && (velocity->size() != d.size() || rate->size() != jacobian.size())))
    throw py::value_error("span's rates must be given together and shaped as d and its Jacobian");
  Array length({k, c}), rows({k, c, n});
  py::object rate_rows = py::none();
  double* out_rate = nullptr;
  if (velocity) {
    Array rates({k, c, n});
    out_rate = rates.mutable_data();
    rate_rows = rates;
  }
  for (py::ssize_t s = 0; s < k * c; ++s) {
    const Eigen::Map<const Eigen::Vector3d> span_s(d.data() + 3 * s);
    const ConstMatrix J(jacobian.data() + 3 * n * s, 3, n);
    const double x = span_s.norm();
    const Eigen::Vector3d u = span_s / x;
    length.mutable_data()[s] = x;
    Row(rows.mutable_data() + n * s, n) = u.transpose() * J;
    if (out_rate) {
      const Eigen::Map<const Eigen::Vector3d> d_dot(velocity->data() + 3 * s);
      const Eigen::Vector3d u_dot = (d_dot - u * u.dot(d_dot)) / x;
      Row(out_rate + n * s, n) =
          u_dot.transpose() * J + u.transpose() * ConstMatrix(rate->data() + 3 * n * s, 3, n);
    }
  }
  return py::make_tuple(length, rows, rate_rows);
}

// (G + λ² I)⁻¹ b for one G = J_H W⁻¹ J_Hᵀ (m, m): λ² = 0 where G is provably conditioned,
// det G ≥ ε (tr G)^m (then σ_min / σ_max ≥ ε, and the Cholesky factor gives det G and the
// solve at once); otherwise λ² = ε σ_max (1 − (σ_min / (ε σ_max))²), clamped to [0, ε σ_max].
Eigen::VectorXd solve_gram(const Eigen::MatrixXd& G, const Eigen::VectorXd& b, double ratio) {
  const Eigen::LLT<Eigen::MatrixXd> factor(G);
  if (factor.info() == Eigen::Success) {
    const double root = factor.matrixLLT().diagonal().prod();
    if (root * root >= ratio * std::pow(G.trace(), double(G.rows()))) return factor.solve(b);
  }
  const Eigen::VectorXd eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(G, Eigen::EigenvaluesOnly).eigenvalues();
  const double threshold = ratio * eigenvalues(eigenvalues.size() - 1);
  const double r = std::clamp(eigenvalues(0) / threshold, 0.0, 1.0);
  const Eigen::MatrixXd damped =
      G + threshold * (1 - r * r) * Eigen::MatrixXd::Identity(G.rows(), G.cols());
  return damped.partialPivLu().solve(b);
}

// The law's kernel, ẋ = J_W⁺ (ẏ − J_H z) + z with J_W⁺ = W⁻¹ J_Hᵀ (J_H W⁻¹ J_Hᵀ)⁻¹, for
// J_H (k, m, n), ẏ (k, m), W (k, n, n) or None for I, z (k, n) or None for 0: ẋ (k, n).
Array resolve(const Array& J_H, const Array& y_dot, const std::optional<Array>& W,
              const std::optional<Array>& z, double ratio) {
  if (J_H.ndim() != 3 || y_dot.ndim() != 2 || y_dot.shape(0) != J_H.shape(0) ||
      y_dot.shape(1) != J_H.shape(1))
    throw py::value_error("resolve takes J_H (k, m, n) and y_dot (k, m)");
  const auto k = J_H.shape(0), m = J_H.shape(1), n = J_H.shape(2);
  if (W && (W->ndim() != 3 || W->shape(0) != k || W->shape(1) != n || W->shape(2) != n))
    throw py::value_error("W must have shape (k, n, n), as J_H (k, m, n)");
  if (z && (z->ndim() != 2 || z->shape(0) != k || z->shape(1) != n))
    throw py::value_error("z must have shape (k, n), as J_H (k, m, n)");
  Array out({k, n});
  for (py::ssize_t i = 0; i < k; ++i) {
    const ConstMatrix J(J_H.data() + i * m * n, m, n);
    const Eigen::MatrixXd W_inv_J_T =
        W ? Eigen::MatrixXd(ConstMatrix(W->data() + i * n * n, n, n).partialPivLu().solve(
                J.transpose()))
          : Eigen::MatrixXd(J.transpose());
    Eigen::VectorXd target = Vector(y_dot.data() + i * m, m);
    if (z) target -= J * Vector(z->data() + i * n, n);
    Eigen::Map<Eigen::VectorXd> x_dot(out.mutable_data() + i * n, n);
    x_dot = W_inv_J_T * solve_gram(J * W_inv_J_T, target, ratio);
    if (z) x_dot += Vector(z->data() + i * n, n);
  }
  return out;
}

PYBIND11_MODULE(_core, m) {
  m.doc() = "The compiled core of redundancy: the batched Pinocchio pass, the cylinders' spans and the laws' kernel.";
  py::class_<Pass>(m, "Pass")
      .def(py::init<std::string, std::vector<pinocchio::FrameIndex>>(), py::arg("model"),
           py::arg("frames"))
      // Robots travel to worker processes (design maps): a pass is sent as what built it.
      .def(py::pickle([](const Pass& pass) { return pass.state(); },
                      [](Pass::State state) {
                        return Pass(std::move(state.first), std::move(state.second));
                      }))
      .def("kinematics", &Pass::kinematics, py::arg("q"), py::arg("v") = py::none())
      .def("mass_matrices", &Pass::mass_matrices, py::arg("q"))
      .def("nonlinear", &Pass::nonlinear, py::arg("q"), py::arg("v"));
  m.def("span", &span, py::arg("d"), py::arg("jacobian"), py::arg("velocity") = py::none(),
        py::arg("rate") = py::none());
  m.def("resolve", &resolve, py::arg("J_H"), py::arg("y_dot"), py::arg("W") = py::none(),
        py::arg("z") = py::none(), py::arg("ratio"));
}
