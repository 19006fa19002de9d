#include "areomap/map/point_cloud_io.h"

#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "test_support.h"

namespace areomap {
namespace {

PointCloud RandomCloud(size_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(-30.0, 30.0);
  PointCloud cloud;
  cloud.frame = "SITE_FRAME site 7";
  cloud.site = 7;
  cloud.camera_center = Eigen::Vector3d(1.0 / 3.0, -2.5e-7, -1.4999999999);
  for (size_t i = 0; i < count; ++i) {
    StereoPoint p;
    p.position = Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
    const Eigen::Matrix3d a = Eigen::Matrix3d::NullaryExpr([&](int, int) { return uniform(rng); });
    const Eigen::Matrix3d c = a * a.transpose() * 1e-4;
    p.covariance = 0.5 * (c + c.transpose());  // Exactly symmetric, as the file stores.
    p.intensity = static_cast<float>(i % 100) / 99.0f;
    p.left_x = static_cast<float>(uniform(rng) + 500.0);
    p.left_y = static_cast<float>(uniform(rng) + 400.0);
    p.image_id = static_cast<uint16_t>(i % 11);
    cloud.points.push_back(p);
  }
  return cloud;
}

TEST(PointCloudPly, RoundTripIsExact) {
  testing::TempDir dir;
  const PointCloud cloud = RandomCloud(1000, 3);
  const auto path = dir.path() / "points.ply";
  WritePointCloudPly(cloud, path);
  const PointCloud back = ReadPointCloudPly(path);
  EXPECT_EQ(back.frame, cloud.frame);
  EXPECT_EQ(back.site, cloud.site);
  EXPECT_EQ(back.camera_center, cloud.camera_center);
  ASSERT_EQ(back.points.size(), cloud.points.size());
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const StereoPoint& a = cloud.points[i];
    const StereoPoint& b = back.points[i];
    EXPECT_EQ(a.position, b.position) << i;
    EXPECT_EQ(a.covariance, b.covariance) << i;
    EXPECT_EQ(a.intensity, b.intensity) << i;
    EXPECT_EQ(a.left_x, b.left_x) << i;
    EXPECT_EQ(a.left_y, b.left_y) << i;
    EXPECT_EQ(a.image_id, b.image_id) << i;
  }
  // Binary size: header + 9 doubles + 3 floats + 1 ushort per point.
  EXPECT_GT(std::filesystem::file_size(path), 1000u * (9 * 8 + 3 * 4 + 2));
}

TEST(PointCloudPly, StreamReaderNamesTheSourceAndHeaderLine) {
  std::istringstream in("ply\nformat ascii 1.0\nend_header\n", std::ios::binary);
  const std::string message = testing::ErrorMessageOf([&] { ReadPointCloudPly(in, "x.ply"); });
  EXPECT_EQ(message,
            "x.ply: PLY header line 2: format 'ascii' is not supported; expected "
            "binary_little_endian");
}

TEST(PointCloudPly, EmptyCloudRoundTrips) {
  testing::TempDir dir;
  PointCloud cloud;
  cloud.site = 0;
  WritePointCloudPly(cloud, dir.path() / "empty.ply");
  const PointCloud back = ReadPointCloudPly(dir.path() / "empty.ply");
  EXPECT_TRUE(back.points.empty());
  EXPECT_EQ(back.frame, "SITE_FRAME");
  EXPECT_EQ(back.site, 0);
}

TEST(PointCloudPly, ReadsPropertiesInAnyOrderAndType) {
  testing::TempDir dir;
  const auto path = dir.path() / "other.ply";
  {
    std::ofstream out(path, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\ncomment areomap_frame SITE_FRAME\n"
           "comment areomap_site 2\ncomment areomap_camera_center 0 0 -1.5\n"
           "element vertex 1\nproperty uchar image_id\nproperty float x\nproperty float y\n"
           "property float z\nproperty float cov_zz\nproperty float cov_yz\nproperty float cov_yy\n"
           "property float cov_xz\nproperty float cov_xy\nproperty float cov_xx\n"
           "property double left_y\nproperty double left_x\nproperty double intensity\n"
           "element face 0\nproperty list uchar int vertex_indices\nend_header\n";
    const uint8_t id = 4;
    out.write(reinterpret_cast<const char*>(&id), 1);
    for (float v : {1.0f, 2.0f, 3.0f, 0.6f, 0.5f, 0.4f, 0.3f, 0.2f, 0.1f}) {
      out.write(reinterpret_cast<const char*>(&v), 4);
    }
    for (double v : {20.0, 10.0, 0.5}) out.write(reinterpret_cast<const char*>(&v), 8);
  }
  const PointCloud cloud = ReadPointCloudPly(path);
  ASSERT_EQ(cloud.points.size(), 1u);
  const StereoPoint& p = cloud.points[0];
  EXPECT_EQ(p.image_id, 4);
  EXPECT_EQ(p.position, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(p.covariance(0, 0), static_cast<double>(0.1f));
  EXPECT_EQ(p.covariance(2, 0), static_cast<double>(0.3f));
  EXPECT_EQ(p.covariance(2, 2), static_cast<double>(0.6f));
  EXPECT_EQ(p.left_x, 10.0f);
  EXPECT_EQ(p.left_y, 20.0f);
  EXPECT_EQ(cloud.site, 2);
  EXPECT_EQ(cloud.camera_center.z(), -1.5);
}

TEST(PointCloudPly, NonFinitePointIsRejectedAndNothingIsWritten) {
  testing::TempDir dir;
  PointCloud cloud = RandomCloud(5, 1);
  cloud.points[3].position.y() = std::numeric_limits<double>::quiet_NaN();
  const auto path = dir.path() / "bad.ply";
  const std::string message = testing::ErrorMessageOf([&] { WritePointCloudPly(cloud, path); });
  EXPECT_NE(message.find("bad.ply"), std::string::npos) << message;
  EXPECT_NE(message.find("point 3"), std::string::npos) << message;
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(PointCloudPly, ErrorsNameTheFileAndTheField) {
  testing::TempDir dir;
  const auto path = dir.path() / "cloud.ply";
  WritePointCloudPly(RandomCloud(10, 2), path);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto write = [&](const std::string& content) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << content;
  };
  auto replace = [&](const std::string& from, const std::string& to) {
    std::string copy = bytes;
    copy.replace(copy.find(from), from.size(), to);
    return copy;
  };

  write(bytes.substr(0, bytes.size() - 7));
  std::string message = testing::ErrorMessageOf([&] { ReadPointCloudPly(path); });
  EXPECT_NE(message.find("cloud.ply"), std::string::npos) << message;
  EXPECT_NE(message.find("truncated"), std::string::npos) << message;

  // A count far beyond the file (a damaged header): the same error, not an allocation failure.
  for (const char* count : {"1000000000000000", "9223372036854775807"}) {
    write(replace("element vertex 10", std::string("element vertex ") + count));
    message = testing::ErrorMessageOf([&] { ReadPointCloudPly(path); });
    EXPECT_NE(message.find("cloud.ply: PLY file is truncated"), std::string::npos) << message;
  }

  write(replace("property double cov_yz", "property double cov_qq"));
  message = testing::ErrorMessageOf([&] { ReadPointCloudPly(path); });
  EXPECT_NE(message.find("'cov_yz'"), std::string::npos) << message;

  write(replace("binary_little_endian", "ascii"));
  message = testing::ErrorMessageOf([&] { ReadPointCloudPly(path); });
  EXPECT_NE(message.find("format 'ascii'"), std::string::npos) << message;

  write(replace("comment areomap_site", "comment something"));
  message = testing::ErrorMessageOf([&] { ReadPointCloudPly(path); });
  EXPECT_NE(message.find("areomap_site"), std::string::npos) << message;

  message = testing::ErrorMessageOf([&] { ReadPointCloudPly(dir.path() / "missing.ply"); });
  EXPECT_NE(message.find("missing.ply"), std::string::npos) << message;
}

}  // namespace
}  // namespace areomap
