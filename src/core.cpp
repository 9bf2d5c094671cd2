// redundancy._core: the one Pinocchio pass over a batch of states, the built-in actuator kinds'
// x with their rows of A and Ȧ, the state's derivation in actuator coordinates (J_H, M_H, N_H,
// q̇), the resolution laws' kernel, and the evaluation of a batch and a control step that run
// them in one call each, the adaptive integration loop with the laws' compiled right-hand side,
// the inverse kinematics' Newton loop and its continuation along a held actuator, and the
// integral optimum's recursion over transitions.
//
// A `Pass` holds a copy of the robot's Pinocchio model (handed over as Pinocchio's own text
// serialization, so that mimic joints, locked joints and added frames arrive exactly as Python
// built them), its own Data, and the tracked frames. Each batch call loops over k states in C++
// and writes numpy arrays, batch axis first.
#include <pybind11/stl.h>

#include "actuators.hpp"
#include "controller.hpp"
#include "integrate.hpp"
#include "law.hpp"
#include "newton.hpp"
#include "pass.hpp"
#include "recursion.hpp"
#include "space.hpp"

PYBIND11_MODULE(_core, m) {
  m.doc() =
      "The compiled core of redundancy: the batched Pinocchio pass, the built-in actuator kinds, "
      "the laws' kernel and the control step.";
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
  m.def("actuate", &actuate_batch, py::arg("kinds"), py::arg("slots"), py::arg("numbers"),
        py::arg("q"), py::arg("positions"), py::arg("jacobians"), py::arg("v") = py::none(),
        py::arg("velocities") = py::none(), py::arg("rates") = py::none());
  m.def("resolve", &resolve, py::arg("J_H"), py::arg("y_dot"), py::arg("W") = py::none(),
        py::arg("z") = py::none(), py::arg("ratio"));
  m.def("held", &held, py::arg("J_H"), py::arg("y_dot"), py::arg("rows"), py::arg("rates"));
  m.def("derive", &derive, py::arg("A"), py::arg("J"), py::arg("tolerance"));
  m.def("inertias", &inertias, py::arg("A"), py::arg("M"));
  m.def("biases", &biases, py::arg("A"), py::arg("N"), py::arg("M_H"), py::arg("A_dot"),
        py::arg("v"));
  m.def("solve", &solve, py::arg("A"), py::arg("B"));
  m.def("accelerated_step", &accelerated_step, py::arg("previous"), py::arg("incoming"),
        py::arg("outgoing"), py::arg("reach"));
  py::class_<Evaluator>(m, "Evaluator")
      .def(py::init<const Pass&, Eigen::Index, std::vector<Eigen::Index>, const py::array_t<int>&,
                    const py::array_t<Eigen::Index>&, const Array&, double>(),
           py::arg("tracking"), py::arg("tool"), py::arg("rows"), py::arg("kinds"),
           py::arg("slots"), py::arg("numbers"), py::arg("tolerance"))
      .def("evaluate",
           py::overload_cast<const py::object&, const py::object&, bool>(&Evaluator::evaluate),
           py::arg("q"), py::arg("v"), py::arg("finite"));
  py::class_<Rates>(m, "Rates")
      .def(py::init<py::object, int, const std::optional<Array>&, const std::optional<Array>&,
                    const std::optional<Array>&, double>(),
           py::arg("evaluator"), py::arg("weight"), py::arg("W"), py::arg("pull"),
           py::arg("middle"), py::arg("ratio"))
      .def(py::init<py::object, std::vector<Eigen::Index>, py::object>(), py::arg("evaluator"),
           py::arg("rows"), py::arg("held"))
      .def(
          "__call__",
          [](Rates& rates, const Array& t, const Array& q, const py::object& velocity) {
            if (q.ndim() != 2) return py::object(py::none());  // Python says what is wrong
            if (t.ndim() != 1 || t.shape(0) != q.shape(0))
              throw py::value_error("t must have shape (r,), one time per state");
            const auto stage =
                rates(Vector(t.data(), t.size()), at(q, 0, q.shape(0), q.shape(1)), velocity, true);
            return stage ? stage->record : py::object(py::none());
          },
          py::arg("t"), py::arg("q"), py::arg("velocity"));
  m.def("dormand_prince", &dormand_prince, py::arg("rates"), py::arg("velocity"), py::arg("q"),
        py::arg("f"), py::arg("failed"), py::arg("duration"), py::arg("breaks"),
        py::arg("same_time"), py::arg("tolerance"), py::arg("c"),
        py::arg("a"), py::arg("e"), py::arg("lower"), py::arg("upper"), py::arg("allowance"),
        py::arg("stop"), py::arg("keep"), py::arg("max_steps"), py::arg("max_singular"));
  m.def("stroke_extremes", &stroke_extremes, py::arg("t"), py::arg("x"), py::arg("x_dot"));
  py::class_<HeldPass>(m, "HeldPass")
      .def(py::init<const Pass&, Eigen::Index, std::vector<Eigen::Index>, const py::array_t<int>&,
                    const py::array_t<Eigen::Index>&, const Array&>(),
           py::arg("tracking"), py::arg("tool"), py::arg("rows"), py::arg("kinds"),
           py::arg("slots"), py::arg("numbers"));
  m.def("newton", &newton, py::arg("pass"), py::arg("q"), py::arg("target"), py::arg("first"),
        py::arg("iterations"), py::arg("bounded"), py::arg("lower"), py::arg("upper"),
        py::arg("tolerance"), py::arg("damping"), py::arg("stalled"));
  m.def("continue_held", &continue_held, py::arg("pass"), py::arg("point"),
        py::arg("known_values"), py::arg("known_q"), py::arg("known_sides"), py::arg("values"),
        py::arg("iterations"), py::arg("lower"), py::arg("upper"), py::arg("bounded"),
        py::arg("tolerance"), py::arg("damping"), py::arg("stalled"), py::arg("found"));
  py::class_<Controller>(m, "Controller")
      .def(py::init<const Pass&, Eigen::Index, std::vector<Eigen::Index>,
                    const py::array_t<int>&, const py::array_t<Eigen::Index>&, const Array&, int,
                    const std::optional<Array>&, const std::optional<Array>&,
                    const std::optional<Array>&, double, double, py::object, py::object,
                    py::object, py::object, bool>(),
           py::arg("tracking"), py::arg("tool"), py::arg("rows"), py::arg("kinds"),
           py::arg("slots"), py::arg("numbers"), py::arg("weight"), py::arg("W"), py::arg("pull"),
           py::arg("middle"), py::arg("ratio"), py::arg("tolerance"), py::arg("fallback"),
           py::arg("result"), py::arg("state_fallback"), py::arg("state"), py::arg("masses"))
      .def("step", &Controller::step, py::arg("q"), py::arg("y_dot"))
      .def("state", &Controller::state, py::arg("q"));
}
