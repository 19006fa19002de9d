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
