#include "convert.h"

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace areomap::python {
namespace {

// The cv::Mat depth of a dtype in the machine's byte order, or -1 where cv::Mat has none.
int DepthOf(const py::dtype& dtype) {
  if (dtype.byteorder() == '>') return -1;  // big-endian data on a little-endian machine
  const char kind = dtype.kind();
  const py::ssize_t size = dtype.itemsize();
  if (kind == 'f') return size == 4 ? CV_32F : size == 8 ? CV_64F : -1;
  if (kind == 'u') return size == 1 ? CV_8U : size == 2 ? CV_16U : -1;
  if (kind == 'i') return size == 1 ? CV_8S : size == 2 ? CV_16S : size == 4 ? CV_32S : -1;
  return -1;
}

}  // namespace

cv::Mat ImageView(const py::array& array, const char* what) {
  if (array.ndim() != 2) {
    throw Error(std::string(what) + ": expected a 2-D array (rows, columns), got " +
                std::to_string(array.ndim()) + " dimensions");
  }
  const int rows = static_cast<int>(array.shape(0));
  const int cols = static_cast<int>(array.shape(1));
  const int depth = DepthOf(array.dtype());
  const bool rows_contiguous = array.strides(1) == array.itemsize() &&
                               array.strides(0) >= array.itemsize() * cols &&
                               array.strides(0) % array.itemsize() == 0;
  if (depth >= 0 && rows_contiguous && rows > 0 && cols > 0) {
    // cv::Mat takes a non-const pointer; the libraries read their inputs only.
    return cv::Mat(rows, cols, CV_MAKETYPE(depth, 1), const_cast<void*>(array.data()),
                   static_cast<size_t>(array.strides(0)));
  }
  const auto copy = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
  if (!copy) throw Error(std::string(what) + ": expected an array of numbers");
  cv::Mat mat(rows, cols, CV_32F);
  if (rows > 0 && cols > 0) {
    std::memcpy(mat.data, copy.data(), sizeof(float) * static_cast<size_t>(rows) * cols);
  }
  return mat;
}

py::array ArrayFromMat(cv::Mat mat) {
  if (mat.empty()) return py::array_t<float>(std::vector<py::ssize_t>{0, 0});
  py::dtype dtype;
  switch (mat.depth()) {
    case CV_8U:
      dtype = py::dtype::of<uint8_t>();
      break;
    case CV_8S:
      dtype = py::dtype::of<int8_t>();
      break;
    case CV_16U:
      dtype = py::dtype::of<uint16_t>();
      break;
    case CV_16S:
      dtype = py::dtype::of<int16_t>();
      break;
    case CV_32S:
      dtype = py::dtype::of<int32_t>();
      break;
    case CV_64F:
      dtype = py::dtype::of<double>();
      break;
    default:
      dtype = py::dtype::of<float>();
      break;
  }
  std::vector<py::ssize_t> shape = {mat.rows, mat.cols};
  std::vector<py::ssize_t> strides = {static_cast<py::ssize_t>(mat.step[0]),
                                      static_cast<py::ssize_t>(mat.elemSize())};
  if (mat.channels() > 1) {
    shape.push_back(mat.channels());
    strides.push_back(static_cast<py::ssize_t>(mat.elemSize1()));
  }
  auto* owner = new cv::Mat(std::move(mat));
  py::capsule capsule(owner, [](void* p) { delete static_cast<cv::Mat*>(p); });
  return py::array(dtype, shape, strides, owner->data, capsule);
}

template <int K>
std::vector<Eigen::Matrix<double, K, 1>> PointsFromArray(const py::handle& array, const char* what,
                                                         bool* single) {
  const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  if (!values || (values.ndim() != 1 && values.ndim() != 2) ||
      values.shape(values.ndim() - 1) != K) {
    throw Error(std::string(what) + ": expected an array of shape (N, " + std::to_string(K) +
                ") or (" + std::to_string(K) + ",) of numbers");
  }
  if (single) *single = values.ndim() == 1;
  const py::ssize_t n = values.ndim() == 1 ? 1 : values.shape(0);
  std::vector<Eigen::Matrix<double, K, 1>> points(static_cast<size_t>(n));
  const double* data = values.data();
  for (py::ssize_t i = 0; i < n; ++i) {
    points[static_cast<size_t>(i)] = Eigen::Map<const Eigen::Matrix<double, K, 1>>(data + K * i);
  }
  return points;
}

template <int K>
py::array ArrayFromPoints(const std::vector<Eigen::Matrix<double, K, 1>>& points, bool single) {
  const auto n = static_cast<py::ssize_t>(points.size());
  py::array_t<double> out = single ? py::array_t<double>(std::vector<py::ssize_t>{K})
                                   : py::array_t<double>(std::vector<py::ssize_t>{n, K});
  double* data = out.mutable_data();
  for (py::ssize_t i = 0; i < n; ++i) {
    Eigen::Map<Eigen::Matrix<double, K, 1>>(data + K * i) = points[static_cast<size_t>(i)];
  }
  return out;
}

template std::vector<Eigen::Vector2d> PointsFromArray<2>(const py::handle&, const char*, bool*);
template std::vector<Eigen::Vector3d> PointsFromArray<3>(const py::handle&, const char*, bool*);
template py::array ArrayFromPoints<2>(const std::vector<Eigen::Vector2d>&, bool);
template py::array ArrayFromPoints<3>(const std::vector<Eigen::Vector3d>&, bool);

py::object FromJson(const nlohmann::json& json) {
  switch (json.type()) {
    case nlohmann::json::value_t::null:
      return py::none();
    case nlohmann::json::value_t::boolean:
      return py::bool_(json.get<bool>());
    case nlohmann::json::value_t::number_integer:
      return py::int_(json.get<int64_t>());
    case nlohmann::json::value_t::number_unsigned:
      return py::int_(json.get<uint64_t>());
    case nlohmann::json::value_t::number_float: {
      // As the JSON files have it: nlohmann::json writes a NaN or an infinity as null.
      const double value = json.get<double>();
      return std::isfinite(value) ? py::object(py::float_(value)) : py::none();
    }
    case nlohmann::json::value_t::string:
      return py::str(json.get<std::string>());
    case nlohmann::json::value_t::array: {
      py::list list;
      for (const nlohmann::json& item : json) list.append(FromJson(item));
      return list;
    }
    case nlohmann::json::value_t::object: {
      py::dict dict;
      for (const auto& [key, value] : json.items()) dict[py::str(key)] = FromJson(value);
      return dict;
    }
    default:
      return py::none();  // binary and discarded values do not occur in results
  }
}

ProgressCallback ProgressBridge::Callback() {
  error_ = nullptr;
  // Captures only the bridge, which outlives the call: copies of the callback may be destroyed
  // on threads that do not hold the GIL.
  return [this](double fraction, std::string_view stage) -> bool {
    py::gil_scoped_acquire acquire;
    if (error_) return false;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (!progress_.is_none()) {
        const py::object answer = progress_(fraction, py::str(stage.data(), stage.size()));
        if (!answer.is_none() && PyObject_IsTrue(answer.ptr()) == 0) return false;
      }
    } catch (py::error_already_set& e) {
      error_ = std::make_shared<py::error_already_set>(std::move(e));
      return false;
    }
    return true;
  };
}

void ProgressBridge::RethrowPythonError() {
  if (error_) {
    const std::shared_ptr<py::error_already_set> error = std::move(error_);
    throw py::error_already_set(*error);
  }
}

}  // namespace areomap::python
