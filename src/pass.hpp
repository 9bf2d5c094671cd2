// The one Pinocchio pass: a copy of the robot's model, its own Data and the tracked frames.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Dense>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>

#include <algorithm>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace py = pybind11;
using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstMatrix = Eigen::Map<const Matrix>;
using Vector = Eigen::Map<const Eigen::VectorXd>;
// A configuration or velocity as Pinocchio's algorithms take it here: the argument type of the
// instantiations compiled into the `pin` wheel's library, which this module links against
// instead of instantiating the algorithms again (PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION).
using Config = Eigen::Ref<const Eigen::VectorXd>;
using Point = Eigen::Map<const Eigen::Vector3d>;
constexpr auto WORLD = pinocchio::LOCAL_WORLD_ALIGNED;

// One state's tracked frames as the actuator kinds read them, laid out as a batch holds each
// state: positions (F, 3), linear Jacobians (F, 3, n) and, moving, the points' velocities (F, 3)
// and Jacobian rates (F, 3, n), row-major.
struct Frames {
  const double* positions;
  const double* jacobians;
  const double* velocities;  // null at rest
  const double* rates;
  Eigen::Index n;

  Point position(Eigen::Index f) const { return Point(positions + 3 * f); }
  ConstMatrix jacobian(Eigen::Index f) const { return ConstMatrix(jacobians + 3 * n * f, 3, n); }
  Point velocity(Eigen::Index f) const { return Point(velocities + 3 * f); }
  ConstMatrix rate(Eigen::Index f) const { return ConstMatrix(rates + 3 * n * f, 3, n); }
  bool moving() const { return velocities != nullptr; }
};

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
    for (auto frame : frames_)
      if (frame >= model_.frames.size())
        throw py::value_error("frame " + std::to_string(frame) + " is not in the model");
    const auto F = frames_.size(), n = std::size_t(model_.nv);
    positions_.resize(3 * F);
    for (std::size_t f = 0; f < F; ++f) {  // a frame on the ground: placed once, J = 0
      const auto& frame = model_.frames[frames_[f]];
      moving_frames_.push_back(frame.parentJoint != 0);
      if (frame.parentJoint == 0)
        Eigen::Map<Eigen::Vector3d>{&positions_[3 * f]} = frame.placement.translation();
    }
    six_ = pinocchio::Data::Matrix6x::Zero(6, model_.nv);
    six_rate_ = six_;
    linear_.resize(3 * F * n);
    angular_.resize(3 * F * n);
    velocities_.resize(3 * F);
    rates_.resize(3 * F * n);
  }

  using State = std::pair<std::string, std::vector<pinocchio::FrameIndex>>;
  State state() const { return {text_, frames_}; }
  Eigen::Index n() const { return model_.nv; }
  Eigen::Index size() const { return Eigen::Index(frames_.size()); }

  // The tracked frames at one state q (n), and with v (n) their velocities and Jacobian rates:
  // what `frames` then reads. The point's J_p = J_v − [p]× J_ω from the spatial (world-frame)
  // Jacobian [J_v; J_ω], so J̇_p = J̇_v − [p]× J̇_ω − [ṗ]× J_ω, with Pinocchio's J̇ of the
  // spatial Jacobian (its world-aligned J̇ at a point leaves a mimic joint's share out of the
  // [ṗ]× J_ω term, in Pinocchio 4.1) and J_ω of the world-aligned Jacobian, mimic joints
  // included in both.
  void at(const double* q, const double* v) {
    const auto n = model_.nv;
    const Config qi = Vector(q, n);
    if (v)
      pinocchio::computeJointJacobiansTimeVariation(model_, data_, qi, Config(Vector(v, n)));
    else
      pinocchio::computeJointJacobians(model_, data_, qi);
    moving_ = v != nullptr;
    for (std::size_t f = 0; f < frames_.size(); ++f) {
      if (!moving_frames_[f]) continue;  // on the ground: as the constructor placed it
      const auto id = frames_[f];
      const auto& frame = model_.frames[id];
      // The point from its joint's placement, and its world-aligned Jacobian from the joint
      // Jacobians by the point alone: what `getFrameJacobian` computes, without the frame's
      // orientation (a 3 × 3 product per frame, an eighth of a state's cost), which a
      // world-aligned Jacobian does not read.
      const Eigen::Vector3d p = data_.oMi[frame.parentJoint].act(frame.placement.translation());
      Eigen::Map<Eigen::Vector3d>{&positions_[3 * f]} = p;
      six_.setZero();
      pinocchio::details::translateJointJacobian(model_, data_, frame.parentJoint, WORLD,
                                                 pinocchio::SE3(Eigen::Matrix3d::Identity(), p),
                                                 data_.J, six_);
      Eigen::Map<Matrix>{&linear_[3 * n * f], 3, n} = six_.topRows<3>();
      Eigen::Map<Matrix>{&angular_[3 * n * f], 3, n} = six_.bottomRows<3>();
      if (v) {  // ṗ = J_p v, and J̇_p from the rate of the spatial Jacobian
        six_rate_.setZero();
        pinocchio::getFrameJacobianTimeVariation(model_, data_, id, pinocchio::WORLD, six_rate_);
        const Eigen::Vector3d p_dot = six_.topRows<3>() * Vector(v, n);
        Eigen::Map<Eigen::Vector3d>{&velocities_[3 * f]} = p_dot;
        Eigen::Map<Matrix> rate{&rates_[3 * n * f], 3, n};
        for (Eigen::Index j = 0; j < n; ++j)
          rate.col(j) = six_rate_.col(j).head<3>() - p.cross(six_rate_.col(j).tail<3>()) -
                        p_dot.cross(six_.col(j).tail<3>());
      }
    }
  }

  // What the last `at` computed.
  Frames frames() const {
    return {positions_.data(), linear_.data(), moving_ ? velocities_.data() : nullptr,
            moving_ ? rates_.data() : nullptr, model_.nv};
  }

  // M(q) (n, n) by CRBA, both triangles filled: in the world convention where the model has
  // mimic joints, as Pinocchio 4.1's default (local) CRBA adds a mimic joint's share to M again
  // at every call where moving joints lie below it (the world one does not, and differs from
  // the local one by rounding elsewhere).
  const Eigen::MatrixXd& mass(const double* q) {
    const Config at(Vector(q, model_.nv));
    if (model_.mimicking_joints.empty())
      pinocchio::crba(model_, data_, at);
    else
      pinocchio::crba(model_, data_, at, pinocchio::Convention::WORLD);
    data_.M.triangularView<Eigen::StrictlyLower>() = data_.M.transpose();
    return data_.M;
  }

  // The arrays of a batch of k states' tracked frames: positions (k, F, 3), linear and angular
  // world-aligned Jacobians (k, F, 3, n) and, `moving`, their velocities (k, F, 3) and linear
  // Jacobian rates (k, F, 3, n) (else None).
  using Outputs = std::tuple<Array, Array, Array, std::optional<Array>, std::optional<Array>>;
  Outputs outputs(py::ssize_t k, bool moving) const {
    const auto F = py::ssize_t(frames_.size()), n = py::ssize_t(model_.nv), three = py::ssize_t(3);
    std::optional<Array> velocities, rates;
    if (moving) {
      velocities = Array({k, F, three});
      rates = Array({k, F, three, n});
    }
    return {Array({k, F, three}), Array({k, F, three, n}), Array({k, F, three, n}), velocities,
            rates};
  }

  // `at` q (n) and v (n) or null, written as state i of the `outputs` arrays; what the actuator
  // kinds read of it.
  Frames write(const double* q, const double* v, py::ssize_t i, Array& positions, Array& linear,
               Array& angular, std::optional<Array>& velocities, std::optional<Array>& rates) {
    at(q, v);
    const auto F = py::ssize_t(frames_.size()), n = py::ssize_t(model_.nv);
    double* p = positions.mutable_data() + i * 3 * F;
    double* J = linear.mutable_data() + i * 3 * F * n;
    std::copy(positions_.begin(), positions_.end(), p);
    std::copy(linear_.begin(), linear_.end(), J);
    std::copy(angular_.begin(), angular_.end(), angular.mutable_data() + i * 3 * F * n);
    if (!v) return {p, J, nullptr, nullptr, n};
    double* pv = velocities->mutable_data() + i * 3 * F;
    double* Jv = rates->mutable_data() + i * 3 * F * n;
    std::copy(velocities_.begin(), velocities_.end(), pv);
    std::copy(rates_.begin(), rates_.end(), Jv);
    return {p, J, pv, Jv, n};
  }

  // Positions (k, F, 3), linear and angular world-aligned Jacobians (k, F, 3, n) of the tracked
  // frames at q (k, n); with v (k, n) also their velocities (k, F, 3) and linear Jacobian rates
  // (k, F, 3, n).
  py::tuple kinematics(const Array& q, const std::optional<Array>& v) {
    const auto k = batch(q, "q");
    if (v) same_batch(*v, k, "v");
    const auto n = py::ssize_t(model_.nv);
    auto [positions, linear, angular, velocities, rates] = outputs(k, v.has_value());
    for (py::ssize_t i = 0; i < k; ++i)
      write(q.data() + i * n, v ? v->data() + i * n : nullptr, i, positions, linear, angular,
            velocities, rates);
    return py::make_tuple(positions, linear, angular, maybe(velocities), maybe(rates));
  }

  // An optional array as Python has it: the array or None.
  static py::object maybe(const std::optional<Array>& a) {
    return a ? py::object(*a) : py::none();
  }

  // M(q) (k, n, n) by CRBA at q (k, n), both triangles filled, and the first state where M has
  // a diagonal entry ≤ 0 (nothing beyond a joint has inertia about it) or is not finite, or −1.
  py::tuple mass_matrices(const Array& q) {
    const auto k = batch(q, "q");
    const auto n = py::ssize_t(model_.nv);
    Array out({k, n, n});
    py::ssize_t still = -1;
    for (py::ssize_t i = 0; i < k; ++i) {
      const auto& M = mass(q.data() + i * n);
      Eigen::Map<Eigen::MatrixXd>(out.mutable_data() + i * n * n, n, n) = M;
      if (still < 0 && (!M.allFinite() || !(M.diagonal().array() > 0).all())) still = i;
    }
    return py::make_tuple(out, still);
  }

  // N(q, v) = V(q, v) + G(q) (k, n) by RNEA.
  Array nonlinear(const Array& q, const Array& v) {
    const auto k = batch(q, "q");
    same_batch(v, k, "v");
    const auto n = py::ssize_t(model_.nv);
    Array out({k, n});
    for (py::ssize_t i = 0; i < k; ++i) {
      const Config qi = Vector(q.data() + i * n, n), vi = Vector(v.data() + i * n, n);
      Eigen::Map<Eigen::VectorXd>(out.mutable_data() + i * n, n) =
          pinocchio::nonLinearEffects(model_, data_, qi, vi);
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
  std::vector<bool> moving_frames_;  // per tracked frame: not fixed to the ground
  pinocchio::Data::Matrix6x six_, six_rate_;
  std::vector<double> positions_, linear_, angular_, velocities_, rates_;  // one state's frames
  bool moving_ = false;
};
