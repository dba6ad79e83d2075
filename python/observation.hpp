#pragma once
// A driver tick as Python sees it: a dict with NumPy arrays, the same in the lock-step module
// (conesim.Sim) and for a Python class driving a `conesim run` (python_driver_plugin.cpp).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <vector>

#include "conesim/sdk/types.hpp"

namespace conesim::python {

namespace py = pybind11;

/// The observation dict: t_s, done, pose [x, y, yaw], speed_mps, yaw_rate_rps, cones (N x 2,
/// vehicle frame) and cone_classes, map (M x 2) and map_classes, map_complete.
inline py::dict observation(double t_s, const sdk::Estimate& estimate, const sdk::ConeFrame& cones,
                            bool done) {
  // positions as an n x 2 array and their classes
  auto places = [](const auto& items) {
    py::array_t<double> xy(std::vector<py::ssize_t>{static_cast<py::ssize_t>(items.size), 2});
    py::array_t<int32_t> classes(static_cast<py::ssize_t>(items.size));
    for (uint64_t i = 0; i < items.size; ++i) {
      xy.mutable_at(i, 0) = items[i].x_m;
      xy.mutable_at(i, 1) = items[i].y_m;
      classes.mutable_at(i) = static_cast<int32_t>(items[i].cls);
    }
    return std::make_pair(xy, classes);
  };
  py::dict d;
  d["t_s"] = t_s;
  d["done"] = done;
  py::array_t<double> pose(3);
  pose.mutable_at(0) = estimate.pose.x_m;
  pose.mutable_at(1) = estimate.pose.y_m;
  pose.mutable_at(2) = estimate.pose.yaw_rad;
  d["pose"] = pose;
  d["speed_mps"] = estimate.speed_mps;
  d["yaw_rate_rps"] = estimate.yaw_rate_rps;
  const auto [cone_xy, cone_classes] = places(cones.cones);
  d["cones"] = cone_xy;
  d["cone_classes"] = cone_classes;
  const auto [map_xy, map_classes] = places(estimate.map);
  d["map"] = map_xy;
  d["map_classes"] = map_classes;
  d["map_complete"] = estimate.map_complete != 0;
  return d;
}

}  // namespace conesim::python
