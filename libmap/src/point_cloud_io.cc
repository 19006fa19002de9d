#include "areomap/map/point_cloud_io.h"

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

static_assert(std::endian::native == std::endian::little,
              "PLY I/O writes the host's bytes as binary_little_endian");

// The properties in the order WritePointCloudPly writes them.
constexpr std::array<const char*, 9> kDoubleProperties = {
    "x", "y", "z", "cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"};
constexpr std::array<const char*, 3> kFloatProperties = {"intensity", "left_x", "left_y"};
constexpr const char* kImageIdProperty = "image_id";
constexpr const char* kFrameComment = "areomap_frame";
constexpr const char* kSiteComment = "areomap_site";
constexpr const char* kCenterComment = "areomap_camera_center";

std::string Format17(double value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

template <typename T>
void Append(std::string& buffer, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  buffer.append(bytes, sizeof(T));
}

// One scalar property of the vertex element as found in a header.
struct PlyProperty {
  std::string type;
  size_t offset = 0;
};

size_t ScalarSize(const std::string& type) {
  static const std::map<std::string, size_t> kSizes = {
      {"char", 1},  {"uchar", 1},   {"int8", 1},   {"uint8", 1},  {"short", 2}, {"ushort", 2},
      {"int16", 2}, {"uint16", 2},  {"int", 4},    {"uint", 4},   {"int32", 4}, {"uint32", 4},
      {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  const auto it = kSizes.find(type);
  return it == kSizes.end() ? 0 : it->second;
}

double ReadScalar(const char* at, const std::string& type) {
  auto get = [at]<typename T>(T) {
    T value;
    std::memcpy(&value, at, sizeof(T));
    return static_cast<double>(value);
  };
  if (type == "char" || type == "int8") return get(int8_t{});
  if (type == "uchar" || type == "uint8") return get(uint8_t{});
  if (type == "short" || type == "int16") return get(int16_t{});
  if (type == "ushort" || type == "uint16") return get(uint16_t{});
  if (type == "int" || type == "int32") return get(int32_t{});
  if (type == "uint" || type == "uint32") return get(uint32_t{});
  if (type == "float" || type == "float32") return get(float{});
  return get(double{});
}

struct PlyHeader {
  size_t vertex_count = 0;
  size_t record_size = 0;
  std::map<std::string, PlyProperty> properties;
  std::map<std::string, std::string> comments;  // areomap_* comment key → rest of the line.
};

PlyHeader ParseHeader(std::istream& in, const std::string& source) {
  PlyHeader header;
  std::string line;
  if (!std::getline(in, line) || line != "ply") {
    throw Error(source + ": not a PLY file: expected 'ply' on the first line");
  }
  bool format_seen = false;
  bool in_vertex = false;
  bool vertex_seen = false;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = source + ": PLY header line " + std::to_string(line_number);
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "end_header") {
      if (!format_seen) throw Error(source + ": PLY header has no 'format' line");
      if (!vertex_seen) throw Error(source + ": PLY header has no 'element vertex'");
      return header;
    }
    if (keyword == "format") {
      std::string format;
      words >> format;
      if (format != "binary_little_endian") {
        throw Error(where + ": format '" + format +
                    "' is not supported; expected binary_little_endian");
      }
      format_seen = true;
    } else if (keyword == "comment" || keyword == "obj_info") {
      std::string key;
      words >> key;
      if (key.rfind("areomap_", 0) == 0) {
        std::string rest;
        std::getline(words >> std::ws, rest);
        header.comments[key] = rest;
      }
    } else if (keyword == "element") {
      std::string name;
      long long count = -1;
      words >> name >> count;
      if (vertex_seen && in_vertex) in_vertex = false;
      if (name == "vertex") {
        if (!words || count < 0) throw Error(where + ": expected 'element vertex <count>'");
        if (vertex_seen) throw Error(where + ": a second 'element vertex'");
        header.vertex_count = static_cast<size_t>(count);
        in_vertex = true;
        vertex_seen = true;
      } else if (!vertex_seen) {
        throw Error(where + ": element '" + name + "' before 'vertex' is not supported");
      }
    } else if (keyword == "property") {
      if (!in_vertex) continue;  // Properties of elements after the vertex block are not read.
      std::string type, name;
      words >> type;
      if (type == "list") throw Error(where + ": list properties in 'vertex' are not supported");
      words >> name;
      const size_t size = ScalarSize(type);
      if (size == 0 || name.empty()) {
        throw Error(where + ": expected 'property <scalar type> <name>', got '" + line + "'");
      }
      header.properties[name] = PlyProperty{type, header.record_size};
      header.record_size += size;
    } else {
      throw Error(where + ": unknown keyword '" + keyword + "'");
    }
  }
  throw Error(source + ": PLY header is truncated: no 'end_header'");
}

const PlyProperty& RequireProperty(const PlyHeader& header, const std::string& name,
                                   const std::string& source) {
  const auto it = header.properties.find(name);
  if (it == header.properties.end()) {
    throw Error(source + ": PLY vertex element lacks property '" + name +
                "'; expected an areomap point cloud (see point_cloud_io.h)");
  }
  return it->second;
}

const std::string& RequireComment(const PlyHeader& header, const std::string& key,
                                  const std::string& source) {
  const auto it = header.comments.find(key);
  if (it == header.comments.end()) {
    throw Error(source + ": PLY header lacks 'comment " + key +
                "'; expected the metadata WritePointCloudPly writes");
  }
  return it->second;
}

}  // namespace

void WritePointCloudPly(const PointCloud& cloud, const std::filesystem::path& path) {
  const std::string source = path.string();
  CheckPointCloud(cloud, source, /*allow_empty=*/true);
  if (cloud.frame.find_first_of("\r\n") != std::string::npos) {
    throw Error(source + ": PointCloud.frame contains a line break; expected one line of text");
  }
  if (!cloud.camera_center.allFinite()) {
    throw Error(source + ": PointCloud.camera_center is not finite");
  }
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by areomap\n";
  header += std::string("comment ") + kFrameComment + " " + cloud.frame + "\n";
  header += std::string("comment ") + kSiteComment + " " + std::to_string(cloud.site) + "\n";
  header += std::string("comment ") + kCenterComment + " " + Format17(cloud.camera_center.x()) +
            " " + Format17(cloud.camera_center.y()) + " " + Format17(cloud.camera_center.z()) +
            "\n";
  header += "element vertex " + std::to_string(cloud.points.size()) + "\n";
  for (const char* name : kDoubleProperties)
    header += std::string("property double ") + name + "\n";
  for (const char* name : kFloatProperties) header += std::string("property float ") + name + "\n";
  header += std::string("property ushort ") + kImageIdProperty + "\nend_header\n";

  constexpr size_t kRecordSize = 9 * sizeof(double) + 3 * sizeof(float) + sizeof(uint16_t);
  std::string body;
  body.reserve(cloud.points.size() * kRecordSize);
  for (const StereoPoint& p : cloud.points) {
    for (int i = 0; i < 3; ++i) Append(body, p.position[i]);
    const Eigen::Matrix3d& c = p.covariance;
    for (double v : {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)}) Append(body, v);
    Append(body, p.intensity);
    Append(body, p.left_x);
    Append(body, p.left_y);
    Append(body, p.image_id);
  }
  AtomicFile file(path);
  {
    std::ofstream out(file.temp_path(), std::ios::binary);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    out.write(body.data(), static_cast<std::streamsize>(body.size()));
    out.close();
    if (!out) throw Error(source + ": write failed");
  }
  file.Commit();
}

PointCloud ReadPointCloudPly(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot open the point cloud file");
  return ReadPointCloudPly(in, path.string());
}

PointCloud ReadPointCloudPly(std::istream& in, const std::string& source) {
  const PlyHeader header = ParseHeader(in, source);

  PointCloud cloud;
  cloud.frame = RequireComment(header, kFrameComment, source);
  {
    std::istringstream site(RequireComment(header, kSiteComment, source));
    if (!(site >> cloud.site)) {
      throw Error(source + ": PLY comment " + kSiteComment + " is not an integer");
    }
    std::istringstream center(RequireComment(header, kCenterComment, source));
    if (!(center >> cloud.camera_center.x() >> cloud.camera_center.y() >>
          cloud.camera_center.z())) {
      throw Error(source + ": PLY comment " + kCenterComment + " is not three numbers");
    }
  }
  std::vector<PlyProperty> doubles, floats;
  for (const char* name : kDoubleProperties)
    doubles.push_back(RequireProperty(header, name, source));
  for (const char* name : kFloatProperties) floats.push_back(RequireProperty(header, name, source));
  const PlyProperty image_id = RequireProperty(header, kImageIdProperty, source);

  // The header's count against what the file holds, before allocating for it: a damaged count
  // (up to 2^63) must be a truncation error, not an allocation failure.
  const auto truncated = [&](std::streamoff got) {
    return Error(source + ": PLY file is truncated: expected " +
                 std::to_string(header.vertex_count) + " vertices of " +
                 std::to_string(header.record_size) + " bytes, got " + std::to_string(got) +
                 " bytes");
  };
  const std::streampos body_start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff available = in.tellg() - body_start;
  in.seekg(body_start);
  if (header.record_size > 0 &&
      header.vertex_count > static_cast<size_t>(available) / header.record_size) {
    throw truncated(available);
  }
  const size_t bytes = header.vertex_count * header.record_size;
  std::vector<char> body(bytes);
  in.read(body.data(), static_cast<std::streamsize>(bytes));
  if (static_cast<size_t>(in.gcount()) != bytes) throw truncated(in.gcount());
  cloud.points.resize(header.vertex_count);
  for (size_t i = 0; i < header.vertex_count; ++i) {
    const char* record = body.data() + i * header.record_size;
    std::array<double, 9> d;
    for (size_t k = 0; k < d.size(); ++k)
      d[k] = ReadScalar(record + doubles[k].offset, doubles[k].type);
    StereoPoint& p = cloud.points[i];
    p.position = Eigen::Vector3d(d[0], d[1], d[2]);
    p.covariance << d[3], d[4], d[5], d[4], d[6], d[7], d[5], d[7], d[8];
    p.intensity = static_cast<float>(ReadScalar(record + floats[0].offset, floats[0].type));
    p.left_x = static_cast<float>(ReadScalar(record + floats[1].offset, floats[1].type));
    p.left_y = static_cast<float>(ReadScalar(record + floats[2].offset, floats[2].type));
    const double id = ReadScalar(record + image_id.offset, image_id.type);
    if (!(id >= 0 && id <= 65535 && id == std::floor(id))) {
      throw Error(source + ": vertex " + std::to_string(i) +
                  ": property image_id is not an integer in [0, 65535]");
    }
    p.image_id = static_cast<uint16_t>(id);
  }
  CheckPointCloud(cloud, source, /*allow_empty=*/true);
  return cloud;
}

}  // namespace areomap
