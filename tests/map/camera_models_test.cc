#include "areomap/map/camera_models.h"

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/camera_footprint.h"
#include "areomap/map/camera_linearize.h"
#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap {
namespace {

// The front Hazcam of ../shared/data/mer/1F490747543EFFCNY9P1214L0M1.IMG (a 124-degree lens),
// copied so the model tests run without the shared data.
CahvoreModel MerHazcam(int type, double parameter) {
  CahvoreModel m;
  m.c = {0.609331, -0.041064, -0.233849};
  m.a = Eigen::Vector3d(0.703447, -0.005161, 0.710729).normalized();
  m.h = {351.362, 452.204, 353.494};
  m.v = {35.8065, -1.75143, 682.705};
  m.o = Eigen::Vector3d(0.704402, -0.006062, 0.709775).normalized();
  m.r = {3e-06, -0.012015, -0.007525};
  m.e = {0.001442, 0.001522, 0.000483};
  m.type = type;
  m.parameter = parameter;
  return m;
}

// Largest pixel error of unproject -> point at 0.3..40 m -> project over a grid of the image.
template <typename Model>
double WorstRoundTrip(const Model& model, int width, int height) {
  double worst = 0.0;
  for (int y = 0; y < height; y += height / 32) {
    for (int x = 0; x < width; x += width / 32) {
      const Eigen::Vector2d pixel(x, y);
      const CameraRay ray = CameraModel(model).Unproject(pixel);
      for (double range : {0.3, 2.0, 40.0}) {
        const auto back = model.Project(ray.origin + range * ray.direction);
        if (!back) return 1e9;
        worst = std::max(worst, (*back - pixel).norm());
      }
    }
  }
  return worst;
}

TEST(Cahvore, RoundTripIsWithinOneHundredthPixelForEachLinearityType) {
  for (const auto& [type, parameter] :
       std::vector<std::pair<int, double>>{{1, 0.0}, {2, 0.0}, {3, 0.37}, {3, -0.4}}) {
    EXPECT_LT(WorstRoundTrip(MerHazcam(type, parameter), 1024, 1024), 0.01)
        << "type " << type << " P " << parameter;
  }
}

TEST(Cahvore, PerspectiveWithoutPupilMovementIsCahvor) {
  // Gennery 2006: with E = 0 and L = 1, CAHVORE reduces to CAHVOR.
  CahvoreModel e = MerHazcam(1, 0.0);
  e.e.setZero();
  e.r = {0.001, -0.02, 0.01};
  CahvorModel r;
  r.c = e.c, r.a = e.a, r.h = e.h, r.v = e.v, r.o = e.o, r.r = e.r;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p = e.c + 3.0 * e.a + Eigen::Vector3d(u(rng), u(rng), u(rng));
    const auto pe = e.Project(p);
    const auto pr = r.Project(p);
    ASSERT_TRUE(pe && pr);
    EXPECT_LT((*pe - *pr).norm(), 1e-9);
  }
}

TEST(Cahvore, FisheyeAngleIsLinearInRadius) {
  // L = 0, R = 0, E = 0: an equidistant fish-eye, image radius = f * theta (Gennery 2006).
  CahvoreModel m = MerHazcam(2, 0.0);
  m.r.setZero();
  m.e.setZero();
  m.o = m.a;
  const double f = 350.0;
  const Eigen::Vector3d right = Eigen::Vector3d::UnitZ().cross(m.a).normalized();
  m.h = f * right + 511.5 * m.a;
  m.v = f * m.a.cross(right) + 511.5 * m.a;
  for (double theta_deg : {10.0, 40.0, 70.0, 95.0}) {
    const double theta = theta_deg * M_PI / 180.0;
    const auto pixel = m.Project(m.c + std::cos(theta) * m.a + std::sin(theta) * right);
    ASSERT_TRUE(pixel) << theta_deg;
    EXPECT_NEAR((*pixel - m.PrincipalPoint()).norm(), f * theta, 1e-6) << theta_deg;
  }
}

TEST(Cahvore, ProjectIsDifferentiableByCeresJets) {
  const CahvoreModel m = MerHazcam(3, 0.37);
  using Jet = ceres::Jet<double, 3>;
  const Eigen::Vector3d p = m.c + Eigen::Vector3d(1.2, 0.7, 0.9);
  const Eigen::Matrix<Jet, 3, 1> pj(Jet(p.x(), 0), Jet(p.y(), 1), Jet(p.z(), 2));
  Eigen::Matrix<Jet, 2, 1> pixel;
  ASSERT_TRUE(m.Project(pj, &pixel));
  for (int k = 0; k < 3; ++k) {
    const double step = 1e-6;
    const Eigen::Vector3d dp = Eigen::Vector3d::Unit(k) * step;
    const Eigen::Vector2d numeric = (*m.Project(p + dp) - *m.Project(p - dp)) / (2.0 * step);
    EXPECT_NEAR(pixel(0).v[k], numeric.x(), 1e-3);
    EXPECT_NEAR(pixel(1).v[k], numeric.y(), 1e-3);
  }
}

PinholeModel K10Left() {
  PinholeModel m;
  m.fu = 620.857971191406;
  m.fv = 622.298034667969;
  m.cu = 526.128784179688;
  m.cv = 374.273742675781;
  m.center = {0.0751, -0.065, -0.902};
  m.world_from_camera << 0.000794376506820371, -0.371711462117335, 0.928347972420126,
      0.997550683961614, -0.0646367856775087, -0.0267342264708707, 0.0699428473375328,
      0.92609539188351, 0.370749677327501;
  m.k1 = -0.331998556852341;
  m.k2 = 0.125557452440262;
  m.p1 = -0.000432605884270742;
  m.p2 = 0.00110327918082476;
  return m;
}

TEST(Pinhole, TsaiFromAStreamNamesTheSourceAndLine) {
  std::istringstream in("VERSION_3\nfu = \nfv = 1\n");
  const std::string message = testing::ErrorMessageOf([&] { ReadTsai(in, "cam.tsai"); });
  EXPECT_EQ(message, "cam.tsai: line 2: key 'fu' has no numbers");
}

TEST(Pinhole, ProjectionMatchesOpenCv) {
  const PinholeModel m = K10Left();
  std::vector<cv::Point3d> points;
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  for (int i = 0; i < 100; ++i) points.emplace_back(u(rng), 0.75 * u(rng), 1.0);
  const cv::Mat k = (cv::Mat_<double>(3, 3) << m.fu, 0, m.cu, 0, m.fv, m.cv, 0, 0, 1);
  const cv::Mat dist = (cv::Mat_<double>(1, 4) << m.k1, m.k2, m.p1, m.p2);
  std::vector<cv::Point2d> expected;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, dist, expected);
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d in_camera(points[i].x, points[i].y, points[i].z);
    const auto pixel = m.Project(Eigen::Vector3d(m.center + m.world_from_camera * in_camera * 3.0));
    ASSERT_TRUE(pixel);
    EXPECT_NEAR(pixel->x(), expected[i].x, 1e-9);
    EXPECT_NEAR(pixel->y(), expected[i].y, 1e-9);
  }
}

TEST(Pinhole, ProjectIsDifferentiableByCeresJets) {
  const PinholeModel m = K10Left();
  using Jet = ceres::Jet<double, 3>;
  const Eigen::Vector3d p = m.center + m.world_from_camera * Eigen::Vector3d(0.6, 0.4, 2.0);
  const Eigen::Matrix<Jet, 3, 1> pj(Jet(p.x(), 0), Jet(p.y(), 1), Jet(p.z(), 2));
  Eigen::Matrix<Jet, 2, 1> pixel;
  ASSERT_TRUE(m.Project(pj, &pixel));
  for (int k = 0; k < 3; ++k) {
    const double step = 1e-6;
    const Eigen::Vector3d dp = Eigen::Vector3d::Unit(k) * step;
    const Eigen::Vector2d numeric = (*m.Project(p + dp) - *m.Project(p - dp)) / (2.0 * step);
    EXPECT_NEAR(pixel(0).v[k], numeric.x(), 1e-3);
    EXPECT_NEAR(pixel(1).v[k], numeric.y(), 1e-3);
  }
}

TEST(Pinhole, RoundTripIsWithinOneHundredthPixel) {
  EXPECT_LT(WorstRoundTrip(K10Left(), 1024, 768), 0.01);
}

TEST(Pinhole, TsaiFileRoundTripsAndReadsTheK10Files) {
  testing::TempDir dir;
  const PinholeModel m = K10Left();
  WriteTsai(m, dir.path() / "cam.tsai");
  const PinholeModel back = ReadTsai(dir.path() / "cam.tsai");
  EXPECT_EQ(back.fu, m.fu);
  EXPECT_EQ(back.cv, m.cv);
  EXPECT_EQ(back.center, m.center);
  EXPECT_EQ(back.world_from_camera, m.world_from_camera);
  EXPECT_EQ(back.p2, m.p2);
  {
    std::ofstream out(dir.path() / "bad.tsai");
    out << "fu = 1\nfv = 1\ncu = 1\n";
  }
  const std::string message = testing::ErrorMessageOf([&] { ReadTsai(dir.path() / "bad.tsai"); });
  EXPECT_NE(message.find("bad.tsai"), std::string::npos) << message;
  EXPECT_NE(message.find("'cv'"), std::string::npos) << message;

  SKIP_WITHOUT_SHARED_DATA();
  const CameraFile left = ReadCameraFile(testing::SharedDataDir() / "k10" / "black_left.tsai");
  const auto& pinhole = std::get<PinholeModel>(left.model.variant());
  EXPECT_EQ(pinhole.fu, m.fu);
  EXPECT_EQ(pinhole.world_from_camera, m.world_from_camera);
}

TEST(Linearize, CahvWithCentredAxisLinearizesToItself) {
  CahvorModel cahv;
  cahv.c = {1, 2, 3};
  cahv.a = Eigen::Vector3d(1, 0.2, 0.3).normalized();
  const Eigen::Vector3d right = Eigen::Vector3d::UnitZ().cross(cahv.a).normalized();
  const Eigen::Vector3d down = cahv.a.cross(right);
  cahv.h = 1200.0 * right + 511.5 * cahv.a;
  cahv.v = 1180.0 * down + 383.5 * cahv.a;
  cahv.o = cahv.a;
  const CahvorModel lin = LinearizeToCahv(cahv, {1024, 768}, {1024, 768});
  EXPECT_LT((lin.c - cahv.c).norm(), 1e-12);
  EXPECT_LT((lin.a - cahv.a).norm(), 1e-12);
  EXPECT_LT((lin.h - cahv.h).norm(), 1e-8);
  EXPECT_LT((lin.v - cahv.v).norm(), 1e-8);
}

// Solves chi (1 + mu(chi)) = chi_d by bisection (independent of the library's Newton).
double UndistortedTangent(const Eigen::Vector3d& r, double chi_d) {
  double lo = 0.0, hi = 2.0 * chi_d;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi), m2 = mid * mid;
    (mid * (1.0 + r.x() + r.y() * m2 + r.z() * m2 * m2) < chi_d ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

TEST(Linearize, RadialDistortionScaleMatchesTheClosedForm) {
  // O = A, principal point centred: the narrowest horizontal ray is the corner's (the
  // distortion grows with radius), and the CAHV scale is ((W - 1) / 2) / its tangent.
  CahvorModel m;
  m.a = Eigen::Vector3d::UnitX();
  m.h = 800.0 * Eigen::Vector3d::UnitY() + 511.5 * m.a;
  m.v = 800.0 * Eigen::Vector3d::UnitZ() + 511.5 * m.a;
  m.o = m.a;
  m.r = {0.0, 0.05, 0.03};
  const double xd = 511.5 / 800.0;
  const double chi_cd = std::sqrt(2.0) * xd;
  const double tan_corner = xd * UndistortedTangent(m.r, chi_cd) / chi_cd;
  const double tan_edge = UndistortedTangent(m.r, xd);
  ASSERT_LT(tan_corner, tan_edge);
  const CahvorModel lin = LinearizeToCahv(m, {1024, 1024}, {1024, 1024});
  EXPECT_NEAR(lin.FocalLengths().x(), 511.5 / tan_corner, 1e-6);
  EXPECT_NEAR(lin.FocalLengths().y(), 511.5 / tan_corner, 1e-6);
  EXPECT_NEAR(lin.PrincipalPoint().x(), 511.5, 1e-9);
}

TEST(Linearize, EveryOutputPixelSeesInsideTheInputImage) {
  for (const CameraModel& model : {CameraModel(MerHazcam(3, 0.37)), CameraModel(K10Left())}) {
    const bool hazcam = model.TypeName() == "CAHVORE";
    const Eigen::Vector2i size = hazcam ? Eigen::Vector2i(1024, 1024) : Eigen::Vector2i(1024, 768);
    const CahvorModel lin = LinearizeToCahv(model, size, size);
    double max_x = -1e9, min_x = 1e9;
    for (int y = 0; y < size.y(); y += 31) {
      for (int x : {0, size.x() - 1}) {
        const Eigen::Vector3d d = lin.Unproject(Eigen::Vector2d(x, y));
        const auto pixel = model.Project(lin.c + 20.0 * d);
        ASSERT_TRUE(pixel);
        EXPECT_GT(pixel->x(), -0.5) << model.TypeName();
        EXPECT_LT(pixel->x(), size.x() - 0.5) << model.TypeName();
        max_x = std::max(max_x, pixel->x());
        min_x = std::min(min_x, pixel->x());
      }
    }
    // Minimum field of view: the innermost of the input's left/right border landmarks (corners
    // and edge midpoints) lands on an output border pixel centre; the others lie outside.
    double innermost = -1e9;  // Landmarks lie outside the output or on its border.
    const double w = size.x() - 1.0, h = size.y() - 1.0;
    for (const Eigen::Vector2d& landmark :
         {Eigen::Vector2d(0, 0), Eigen::Vector2d(0, h / 2), Eigen::Vector2d(0, h),
          Eigen::Vector2d(w, 0), Eigen::Vector2d(w, h / 2), Eigen::Vector2d(w, h)}) {
      const CameraRay ray = model.Unproject(landmark);
      const auto in_lin = lin.Project(Eigen::Vector3d(lin.c + ray.direction));
      if (!in_lin) continue;  // A fish-eye corner can be more than 90 degrees off the axis.
      const double x = in_lin->x();
      innermost = std::max(innermost, landmark.x() == 0 ? x : w - x);
    }
    EXPECT_NEAR(innermost, 0.0, 1e-6) << model.TypeName() << " " << min_x << " " << max_x;
  }
}

TEST(CameraFile, LabelsWriteAndReadBack) {
  testing::TempDir dir;
  const CameraModel hazcam = MerHazcam(3, 0.37);
  WriteCameraFile(hazcam, "ROVER_FRAME", dir.path() / "hazcam.json");
  const CameraFile back = ReadCameraFile(dir.path() / "hazcam.json");
  EXPECT_EQ(back.frame, "ROVER_FRAME");
  const auto& m = std::get<CahvoreModel>(back.model.variant());
  EXPECT_EQ(m.e, MerHazcam(3, 0.37).e);
  EXPECT_EQ(m.type, 3);
  EXPECT_EQ(m.parameter, 0.37);
  // A missing image is named as missing, not as an image without a camera.
  const std::string missing =
      testing::ErrorMessageOf([&] { ReadCameraForImage(dir.path() / "nothing.png"); });
  EXPECT_NE(missing.find("nothing.png: no such file"), std::string::npos) << missing;
  std::ofstream(dir.path() / "bare.png") << "pixels";
  const std::string message =
      testing::ErrorMessageOf([&] { ReadCameraForImage(dir.path() / "bare.png"); });
  EXPECT_NE(message.find("bare.png"), std::string::npos) << message;
  EXPECT_NE(message.find("no camera model"), std::string::npos) << message;

  // An image size stated but not positive is an error naming the file and the key.
  nlohmann::json label = nlohmann::json::parse(std::ifstream(dir.path() / "hazcam.json"));
  label["IMAGE"] = {{"LINES", -5}, {"LINE_SAMPLES", 1024}};
  std::ofstream(dir.path() / "negative.json") << label.dump();
  const std::string negative =
      testing::ErrorMessageOf([&] { ReadCameraFile(dir.path() / "negative.json"); });
  EXPECT_NE(negative.find("negative.json: IMAGE.LINES is -5"), std::string::npos) << negative;
  label["IMAGE"]["LINES"] = 1024;
  std::ofstream(dir.path() / "positive.json") << label.dump();
  const auto size = ReadCameraFile(dir.path() / "positive.json").image_size;
  ASSERT_TRUE(size.has_value());
  EXPECT_EQ(size->x(), 1024);
  EXPECT_EQ(size->y(), 1024);
}

TEST(CameraFile, RealMerHazcamAndNavcamLabels) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto mer = testing::SharedDataDir() / "mer";
  const CameraFile hazcam = ReadCameraFile(mer / "1F490747543EFFCNY9P1214L0M1.IMG");
  EXPECT_EQ(hazcam.model.TypeName(), "CAHVORE");
  const auto& h = std::get<CahvoreModel>(hazcam.model.variant());
  EXPECT_EQ(h.type, 3);
  EXPECT_DOUBLE_EQ(h.parameter, 0.37);
  EXPECT_LT(WorstRoundTrip(h, 1024, 1024), 0.01);
  ASSERT_TRUE(hazcam.site_from_frame.has_value());
  EXPECT_EQ(hazcam.site, 195);
  const CameraFile navcam = ReadCameraFile(mer / "1N491020376ILFCNY9P0706L0M1.IMG");
  EXPECT_EQ(navcam.model.TypeName(), "CAHVOR");
  ASSERT_TRUE(navcam.site_from_frame.has_value());
  // The label's rover->site quaternion and offset, applied to the rover origin and the camera.
  EXPECT_LT((*navcam.site_from_frame * Eigen::Vector3d::Zero() -
             Eigen::Vector3d(73.9193, 65.9703, 6.56288))
                .norm(),
            1e-9);
  // Same rover pose: both cameras' centres in the site frame are within the mast's reach.
  const Eigen::Vector3d hazcam_in_site = *hazcam.site_from_frame * hazcam.model.Center();
  const Eigen::Vector3d navcam_in_site = *navcam.site_from_frame * navcam.model.Center();
  EXPECT_LT((hazcam_in_site - navcam_in_site).norm(), 1.5);
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

TEST(Footprint, NadirCahvSeesTheRectangleOfItsFieldOfView) {
  CahvorModel m;  // 1.5 m above the ground (z down), looking straight down.
  m.c = {0.0, 0.0, -1.5};
  m.a = Eigen::Vector3d::UnitZ();
  m.h = 500.0 * Eigen::Vector3d::UnitY() + 99.5 * m.a;   // Image x -> east.
  m.v = 400.0 * -Eigen::Vector3d::UnitX() + 49.5 * m.a;  // Image y -> south.
  m.o = m.a;
  const auto polygon = GroundFootprint(m, {200, 100}, 0.0, 30.0);
  // Half extents: 1.5 m x (99.5 / 500) east-west and 1.5 m x (49.5 / 400) north-south.
  EXPECT_NEAR(PolygonArea(polygon), 4.0 * (1.5 * 99.5 / 500.0) * (1.5 * 49.5 / 400.0), 1e-9);
  for (const Eigen::Vector2d& p : polygon) {
    EXPECT_LE(std::abs(p.y()), 1.5 * 99.5 / 500.0 + 1e-9);
    EXPECT_LE(std::abs(p.x()), 1.5 * 49.5 / 400.0 + 1e-9);
  }
}

TEST(Footprint, MerPanFramesPointAsTheirLabelsSay) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto mer = testing::SharedDataDir() / "mer";
  std::vector<double> azimuths;
  std::vector<std::vector<Eigen::Vector2d>> footprints;
  for (const char* name : {"1N491020376ILFCNY9P0706L0M1.IMG", "1N491020519ILFCNY9P0706L0M1.IMG"}) {
    const CameraFile file = ReadCameraFile(mer / name);
    ASSERT_TRUE(file.site_from_frame && file.image_size);
    const CameraModel in_site = file.model.Transformed(*file.site_from_frame);
    const CahvorModel linear = LinearizeToCahv(in_site, *file.image_size, *file.image_size);
    azimuths.push_back(std::atan2(linear.a.y(), linear.a.x()) * 180.0 / M_PI);
    const double ground_z = file.site_from_frame->translation.z();
    footprints.push_back(GroundFootprint(in_site, *file.image_size, ground_z, 30.0));
  }
  // SITE_DERIVED_GEOMETRY_PARMS INSTRUMENT_AZIMUTH of the two labels: 90.0019 and 126.005 deg
  // (JPL's own rover->site chaining of the pointing).
  EXPECT_NEAR(azimuths[0], 90.0019, 0.1);
  EXPECT_NEAR(azimuths[1], 126.005, 0.1);
  // 45 degree frames 36 degrees apart: the footprints overlap on a wedge of about 9 degrees.
  std::vector<cv::Point2f> a, b, overlap;
  for (const auto& p : footprints[0])
    a.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  for (const auto& p : footprints[1])
    b.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  std::vector<cv::Point2f> hull_a, hull_b;
  cv::convexHull(a, hull_a);
  cv::convexHull(b, hull_b);
  const double shared = cv::intersectConvexConvex(hull_a, hull_b, overlap);
  const double fraction = shared / PolygonArea(footprints[0]);
  EXPECT_GT(fraction, 0.5 * 9.0 / 45.0);
  EXPECT_LT(fraction, 2.0 * 9.0 / 45.0);
}

}  // namespace
}  // namespace areomap
