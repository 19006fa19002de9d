#include "areomap/registration/orbital_report.h"

#include <cmath>

#include <gtest/gtest.h>

#include "areomap/registration/orbital_grid.h"
#include "orbital_trial.h"
#include "test_support.h"

namespace areomap {
namespace {

class OrbitalReportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    testing::TrialOptions o;
    o.seed = 21;
    o.orbital_half_extent_m = 35.0;
    o.ortho_half_extent_m = 15.0;
    o.telemetry_sigma_m = 2.0;
    o.decoy = false;
    trial_ = new testing::Trial(testing::MakeTrial(o));
    trial_->ortho.site = 3;
    trial_->ortho.site_origin = trial_->prior.position;
    match_ = new OrbitalMatch(MatchOrthoToOrbital(trial_->ortho, *trial_->orbital, trial_->prior));
  }
  static void TearDownTestSuite() {
    delete match_;
    delete trial_;
  }
  static testing::Trial* trial_;
  static OrbitalMatch* match_;
};
testing::Trial* OrbitalReportTest::trial_ = nullptr;
OrbitalMatch* OrbitalReportTest::match_ = nullptr;

TEST_F(OrbitalReportTest, ControlPointsLieWhereTheTruthIs) {
  ASSERT_TRUE(match_->matched) << match_->BriefReport();
  const testing::Trial& t = *trial_;
  const std::vector<OrbitalControlPoint> points =
      MakeControlPoints(*match_, t.ortho, *t.orbital, t.prior, t.dtm);
  ASSERT_GE(points.size(), 3u);
  const PixelGrid truth(t.ortho_truth, t.ortho.crs_wkt, "truth");
  const Body body = Body::Mars2000();
  for (const OrbitalControlPoint& p : points) {
    SCOPED_TRACE(p.point.id);
    // Where the ortho pixel truly is on the ground, at the DTM's height.
    const auto g = truth.PixelToGeographic(p.ortho_px);
    ASSERT_TRUE(g.has_value());
    const Eigen::Vector3d true_mbf = MbfOnRadialLine(body, g->lat, g->lon, p.geographic.h);
    const Rigid3d enu_from_mbf = EnuFromMbf(body, *g);
    const Eigen::Vector3d e = enu_from_mbf.RotationMatrix() * (p.point.position_mbf - true_mbf);
    // Horizontal: within half an orbital pixel (the match's accuracy); vertical: exact here.
    EXPECT_LE(e.head<2>().norm(), 0.5 * t.gsd_m);
    EXPECT_NEAR(e.z(), 0.0, 1e-3);
    EXPECT_TRUE(p.height_from_dtm);
    EXPECT_NEAR(p.sigma_up_m, 1.0, 1e-12);
    // The covariance in MBF has the ENU variances on its principal axes; the shared shift's
    // covariance is spread over the points (n times each).
    const double n = static_cast<double>(points.size());
    const double trace_enu = n * match_->shift_covariance_en_m2.trace() + 1.0;
    EXPECT_NEAR(p.point.covariance_mbf.trace(), trace_enu, 1e-9);
    // Site frame (x north, y east, z down) of the telemetry origin: the telemetry position.
    EXPECT_EQ(p.point.site, 3);
    EXPECT_LT(p.point.position_in_site.head<2>().norm(), 30.0);
  }
  // JSON and CSV carry every point.
  EXPECT_EQ(ControlPointsJson(points).size(), points.size());
  const std::string csv = ControlPointsCsv(points);
  EXPECT_EQ(static_cast<size_t>(std::count(csv.begin(), csv.end(), '\n')), points.size() + 1);
}

// A low correlation's share of the rotation's error moves each control point across its lever
// from the pivot: the points' covariance grows there, by n x sigma^2 x lever^2, and not along it.
TEST_F(OrbitalReportTest, ControlPointsCarryALowCorrelationsTurnAcrossTheirLever) {
  ASSERT_TRUE(match_->matched) << match_->BriefReport();
  const testing::Trial& t = *trial_;
  OrbitalMatch turned = *match_;
  turned.low_correlation_rotation_sigma_rad = RadFromDeg(0.5);
  turned.rotation_pivot_px = match_->centre_px + Eigen::Vector2d(7.0, -4.0);
  const std::vector<OrbitalControlPoint> plain =
      MakeControlPoints(*match_, t.ortho, *t.orbital, t.prior, t.dtm);
  const std::vector<OrbitalControlPoint> points =
      MakeControlPoints(turned, t.ortho, *t.orbital, t.prior, t.dtm);
  ASSERT_EQ(points.size(), plain.size());
  ASSERT_GE(points.size(), 3u);
  const double n = static_cast<double>(points.size());
  const PixelGrid grid(t.orbital->geotransform(), t.orbital->crs_wkt(), "orbital");
  const Body body = Body::Mars2000();
  double longest_m = 0.0;
  for (size_t i = 0; i < points.size(); ++i) {
    SCOPED_TRACE(points[i].point.id);
    EXPECT_EQ(points[i].point.position_mbf, plain[i].point.position_mbf);
    const Eigen::Matrix3d enu_from_mbf = EnuFromMbf(body, points[i].geographic).RotationMatrix();
    const Eigen::Matrix2d extra =
        (enu_from_mbf * (points[i].point.covariance_mbf - plain[i].point.covariance_mbf) *
         enu_from_mbf.transpose())
            .topLeftCorner<2, 2>();
    // The point's offset from the pivot, east and north [m], where telemetry put both.
    const Eigen::Vector2d at_telemetry = turned.OrbitalToTemplate(points[i].orbital_px) +
                                         Eigen::Vector2d(turned.templ.col0, turned.templ.row0);
    const Eigen::Vector2d offset_m =
        grid.EastNorthPerPixel(points[i].orbital_px) * (at_telemetry - turned.rotation_pivot_px);
    longest_m = std::max(longest_m, offset_m.norm());
    const double expected =
        n * std::pow(turned.low_correlation_rotation_sigma_rad, 2) * offset_m.squaredNorm();
    EXPECT_NEAR(extra.trace(), expected, 1e-6 * expected + 1e-12);
    const Eigen::Vector2d along = offset_m.normalized();
    EXPECT_NEAR(along.dot(extra * along), 0.0, 1e-6 * expected + 1e-12);
  }
  EXPECT_GT(longest_m, 5.0);  // Some points have a lever worth the name.
}

TEST_F(OrbitalReportTest, CorrectedGeoTransformPutsTheOrthoOnTheTruth) {
  ASSERT_TRUE(match_->matched);
  const testing::Trial& t = *trial_;
  const GeoTransform corrected = CorrectedGeoTransform(*match_, t.ortho, *t.orbital);
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(150, 150), Eigen::Vector2d(300, 40)}) {
    const Eigen::Vector2d error =
        corrected.PixelToMap(p.x(), p.y()) - t.ortho_truth.PixelToMap(p.x(), p.y());
    EXPECT_LE(error.norm(), 0.5 * t.gsd_m) << p.transpose();
  }
}

TEST_F(OrbitalReportTest, SurfacePictureAndMatchJson) {
  const cv::Mat picture = CorrelationSurfaceImage(*match_, 4);
  EXPECT_EQ(picture.type(), CV_8UC3);
  EXPECT_EQ(picture.rows, match_->surface.rows * 4);
  const nlohmann::json j = MatchJson(*match_);
  EXPECT_EQ(j["matched"], true);
  EXPECT_NEAR(j["shift_east_m"].get<double>(), match_->shift_en_m.x(), 1e-12);
  // No match: no control points.
  OrbitalMatch none = *match_;
  none.matched = false;
  EXPECT_TRUE(MakeControlPoints(none, trial_->ortho, *trial_->orbital, trial_->prior, {}).empty());
}

}  // namespace
}  // namespace areomap
