// What every binding of the Python module shares: NumPy arrays to and from cv::Mat and Eigen
// point lists, JSON (the libraries' own serialisation of results) to Python objects, and the
// bridge from a Python progress callable (and Ctrl-C) to an areomap::ProgressCallback.
#pragma once

#include <exception>
#include <memory>
#include <utility>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "areomap/map/error.h"
#include "areomap/map/progress.h"

namespace areomap::python {

namespace py = pybind11;

// A cv::Mat over a 2-D array's memory, without a copy, when the array's dtype is one cv::Mat
// has (uint8, int8, uint16, int16, int32, float32, float64) and its rows are contiguous (any row
// stride): a C-contiguous float32 array is used in place. Other arrays (another dtype, columns
// not adjacent) are copied into a float32 matrix. The caller keeps `array` alive while the Mat
// is used. Throws areomap::Error naming `what` unless the array is 2-D.
cv::Mat ImageView(const py::array& array, const char* what);

// A NumPy array that owns `mat` (moved into it; no copy of the pixels). 2-D for one channel.
py::array ArrayFromMat(cv::Mat mat);

// An N x K array (or one point of K values), anything NumPy converts to float64 (a list too), as
// N points; `single` (when given) tells whether it was one point. `what` names it in errors.
// Throws areomap::Error unless the last dimension is K.
template <int K>
std::vector<Eigen::Matrix<double, K, 1>> PointsFromArray(const py::handle& array, const char* what,
                                                         bool* single = nullptr);
// N points back as an N x K float64 array (K values for one point when `single`).
template <int K>
py::array ArrayFromPoints(const std::vector<Eigen::Matrix<double, K, 1>>& points, bool single);

// JSON as Python objects as its file would read back: objects -> dict, arrays -> list, null and
// non-finite numbers -> None.
py::object FromJson(const nlohmann::json& json);

// Runs a long library call without the GIL. `progress`, when not None, is called as
// progress(fraction, stage) with the GIL held; returning False cancels the call (an
// areomap.Error "cancelled ..." in Python), raising an exception stops it and re-raises that
// exception. Pending signals are checked at every progress step, so Ctrl-C stops the call with
// KeyboardInterrupt (when the step runs on the main thread).
class ProgressBridge {
 public:
  explicit ProgressBridge(py::object progress) : progress_(std::move(progress)) {}
  ProgressCallback Callback();
  // Calls `call(callback)` without the GIL; translates a cancellation caused by a Python
  // exception back into that exception.
  template <typename Call>
  auto Run(Call&& call) -> decltype(call(std::declval<const ProgressCallback&>())) {
    const ProgressCallback callback = Callback();
    try {
      py::gil_scoped_release release;
      return call(callback);
    } catch (const Error&) {
      RethrowPythonError();
      throw;
    }
  }

 private:
  void RethrowPythonError();
  py::object progress_;
  std::shared_ptr<py::error_already_set> error_;
};

// A call without a progress hook, still without the GIL.
template <typename Call>
auto WithoutGil(Call&& call) -> decltype(call()) {
  py::gil_scoped_release release;
  return call();
}

}  // namespace areomap::python
