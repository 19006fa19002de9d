#include "areomap/map/camera_pinhole.h"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {

std::optional<Eigen::Vector2d> PinholeModel::Project(const Eigen::Vector3d& point) const {
  Eigen::Vector2d pixel;
  if (!Project<double>(point, &pixel)) return std::nullopt;
  return pixel;
}

CameraRay PinholeModel::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() * pitch - cu) / fu, (pixel.y() * pitch - cv) / fv);
  // Newton on the 2x2 distortion map, starting from the distorted point.
  Eigen::Vector2d n = distorted;
  for (int i = 0; i < 50; ++i) {
    const double x = n.x(), y = n.y(), r2 = x * x + y * y;
    const double radial = 1.0 + k1 * r2 + k2 * r2 * r2;
    const double dradial = k1 + 2.0 * k2 * r2;  // d radial / d r2
    const Eigen::Vector2d f(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
    Eigen::Matrix2d j;
    j(0, 0) = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
    j(0, 1) = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
    j(1, 0) = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
    j(1, 1) = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
    const Eigen::Vector2d step = j.lu().solve(f - distorted);
    n -= step;
    if (step.norm() < 1e-14) break;
  }
  const Eigen::Vector3d in_camera = n.x() * u_direction + n.y() * v_direction + w_direction;
  return CameraRay{center, (world_from_camera * in_camera).normalized()};
}

PinholeModel PinholeModel::Transformed(const Rigid3d& b_from_a) const {
  PinholeModel out = *this;
  out.center = b_from_a * center;
  out.world_from_camera = b_from_a.RotationMatrix() * world_from_camera;
  return out;
}

PinholeModel ReadTsai(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open the .tsai camera file");
  return ReadTsai(in, path.string());
}

PinholeModel ReadTsai(std::istream& in, const std::string& source) {
  std::map<std::string, std::vector<double>> values;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const size_t eq = line.find('=');
    if (eq == std::string::npos) continue;  // VERSION_n, PINHOLE, TSAI lines carry no value.
    std::string key = line.substr(0, eq);
    key.erase(key.find_last_not_of(" \t") + 1);
    key.erase(0, key.find_first_not_of(" \t"));
    std::istringstream numbers(line.substr(eq + 1));
    std::vector<double> list;
    double v = 0.0;
    while (numbers >> v) list.push_back(v);
    if (list.empty()) {
      throw Error(source + ": line " + std::to_string(number) + ": key '" + key +
                  "' has no numbers");
    }
    values[key] = list;
  }
  const auto get = [&](const std::string& key, size_t count) -> const std::vector<double>& {
    const auto it = values.find(key);
    if (it == values.end()) {
      throw Error(source + ": .tsai key '" + key + "' is missing");
    }
    if (it->second.size() != count) {
      throw Error(source + ": .tsai key '" + key + "' has " + std::to_string(it->second.size()) +
                  " numbers: expected " + std::to_string(count));
    }
    return it->second;
  };
  const auto vec3 = [&](const std::string& key) {
    const auto& v = get(key, 3);
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  PinholeModel m;
  m.fu = get("fu", 1)[0];
  m.fv = get("fv", 1)[0];
  m.cu = get("cu", 1)[0];
  m.cv = get("cv", 1)[0];
  m.u_direction = vec3("u_direction");
  m.v_direction = vec3("v_direction");
  m.w_direction = vec3("w_direction");
  m.center = vec3("C");
  const auto& r = get("R", 9);
  m.world_from_camera << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
  m.k1 = get("k1", 1)[0];
  m.k2 = get("k2", 1)[0];
  m.p1 = get("p1", 1)[0];
  m.p2 = get("p2", 1)[0];
  if (values.count("pitch")) m.pitch = get("pitch", 1)[0];
  if (!(m.fu > 0.0 && m.fv > 0.0 && m.pitch > 0.0)) {
    throw Error(source + ": .tsai fu, fv and pitch must be positive");
  }
  const Eigen::Matrix3d rtr = m.world_from_camera.transpose() * m.world_from_camera;
  if (!((rtr - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6) ||
      m.world_from_camera.determinant() < 0.0) {
    throw Error(source + ": .tsai R is not a rotation matrix (R^T R != I or det < 0)");
  }
  return m;
}

std::string FormatTsai(const PinholeModel& m) {
  std::ostringstream out;
  out.precision(17);
  const auto vec = [&](const char* key, const Eigen::Vector3d& v) {
    out << key << " = " << v.x() << " " << v.y() << " " << v.z() << "\n";
  };
  out << "VERSION_3\nPINHOLE\n";
  out << "fu = " << m.fu << "\nfv = " << m.fv << "\ncu = " << m.cu << "\ncv = " << m.cv << "\n";
  vec("u_direction", m.u_direction);
  vec("v_direction", m.v_direction);
  vec("w_direction", m.w_direction);
  vec("C", m.center);
  out << "R =";
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out << " " << m.world_from_camera(i, j);
  }
  out << "\npitch = " << m.pitch << "\nTSAI\n";
  out << "k1 = " << m.k1 << "\nk2 = " << m.k2 << "\np1 = " << m.p1 << "\np2 = " << m.p2 << "\n";
  return out.str();
}

void WriteTsai(const PinholeModel& model, const std::filesystem::path& path) {
  WriteFileAtomically(path, FormatTsai(model));
}

}  // namespace areomap
