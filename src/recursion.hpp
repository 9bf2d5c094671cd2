// The step of the integral optimum's dynamic programming whose state is the transition into a
// node (`redundancy.planning.integral_optimum._pass`), so that an acceleration limit is checked
// on every path: for each transition (c, d), the least cost V(b, c) among the transitions into
// c whose rates differ from its own by at most h ẍ_max in every limited actuator.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

namespace py = pybind11;

using Costs = py::array_t<double, py::array::c_style | py::array::forcecast>;

// previous V(b, c) (G, G), incoming ẋ(b, c) (G, G, K), outgoing ẋ(c, d) (G, G, K), reach
// (K,) → the least V(b, c) over the b that keep |ẋ(c, d) − ẋ(b, c)| ≤ reach, (G, G), and that
// b, (G, G), inf and −1 where none does. For each c the b are tried in the order of V(b, c)
// (ties: the lower b), so the first one that keeps the limits is the least: at most G³ K
// comparisons, far fewer where the cheapest predecessors keep them.
inline std::pair<py::array_t<double>, py::array_t<std::int32_t>> accelerated_step(
    const Costs& previous, const Costs& incoming, const Costs& outgoing, const Costs& reach) {
  const auto G = previous.ndim() == 2 ? previous.shape(0) : -1;
  const auto K = reach.ndim() == 1 ? reach.shape(0) : -1;
  const auto shaped = [&](const Costs& a) {
    return a.ndim() == 3 && a.shape(0) == G && a.shape(1) == G && a.shape(2) == K;
  };
  if (G < 0 || previous.shape(1) != G || K < 0 || !shaped(incoming) || !shaped(outgoing))
    throw py::value_error("accelerated_step takes V (G, G), two rates (G, G, K) and reach (K,)");
  py::array_t<double> best({G, G});
  py::array_t<std::int32_t> choice({G, G});
  const double *V = previous.data(), *in = incoming.data(), *out = outgoing.data();
  const double* limit = reach.data();
  double* least = best.mutable_data();
  std::int32_t* from = choice.mutable_data();
  {
    py::gil_scoped_release release;
    std::vector<py::ssize_t> order;
    order.reserve(G);
    for (py::ssize_t c = 0; c < G; ++c) {
      order.clear();
      for (py::ssize_t b = 0; b < G; ++b)
        if (std::isfinite(V[b * G + c])) order.push_back(b);
      std::stable_sort(order.begin(), order.end(),
                       [&](auto a, auto b) { return V[a * G + c] < V[b * G + c]; });
      for (py::ssize_t d = 0; d < G; ++d) {
        const double* rate = out + (c * G + d) * K;
        least[c * G + d] = std::numeric_limits<double>::infinity();
        from[c * G + d] = -1;
        for (const auto b : order) {
          const double* before = in + (b * G + c) * K;
          py::ssize_t k = 0;
          while (k < K && std::abs(rate[k] - before[k]) <= limit[k]) ++k;
          if (k == K) {
            least[c * G + d] = V[b * G + c];
            from[c * G + d] = static_cast<std::int32_t>(b);
            break;
          }
        }
      }
    }
  }
  return {best, choice};
}
