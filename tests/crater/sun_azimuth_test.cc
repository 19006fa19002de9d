#include "areomap/crater/sun_azimuth.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "areomap/map/raster.h"
#include "crater_scene.h"
#include "test_support.h"

namespace areomap {
namespace {

double AngleBetweenDeg(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 360.0);
  return std::min(d, 360.0 - d);
}

TEST(SunAzimuth, RecoversTheRenderersSunFromCratersFoundWithoutIt) {
  for (const double truth : {30.0, 120.0, 215.0, 300.0}) {
    const cv::Mat image = testing::MakeFieldScene(truth).products.image.bands[0];
    const std::vector<CraterDetection> found = DetectCraters(image, RimSource::kImage);
    const SunAzimuthEstimate e = EstimateSunAzimuth(image, found);
    std::printf("sun %.0f deg: estimated %.1f from %d votes of %d candidates, agreement %.2f\n",
                truth, e.azimuth_deg, e.votes, e.candidates, e.agreement);
    EXPECT_TRUE(e.reliable) << truth;
    // A bowl's dipole points straight away from the sun; 10 degrees leaves room for craters
    // cut by their neighbours and the terrain's own slopes.
    EXPECT_LT(AngleBetweenDeg(e.azimuth_deg, truth), 10.0) << truth;
  }
}

TEST(SunAzimuth, NothingToVoteIsNotReliable) {
  const cv::Mat flat(400, 400, CV_32F, cv::Scalar(0.3));
  const SunAzimuthEstimate none = EstimateSunAzimuth(flat, DetectCraters(flat, RimSource::kImage));
  EXPECT_EQ(none.candidates, 0);
  EXPECT_EQ(none.votes, 0);
  EXPECT_TRUE(std::isnan(none.azimuth_deg));
  EXPECT_FALSE(none.reliable);
  // A candidate on a flat patch shows no dipole: no vote.
  CraterDetection fake;
  fake.ellipse.center = {200.0, 200.0};
  fake.ellipse.semi_major = fake.ellipse.semi_minor = 30.0;
  const SunAzimuthEstimate flat_vote = EstimateSunAzimuth(flat, {fake});
  EXPECT_EQ(flat_vote.candidates, 1);
  EXPECT_EQ(flat_vote.votes, 0);
  EXPECT_FALSE(flat_vote.reliable);
}

// The real HRSC image: no label gives its sun; its craters' shadows lie on their west inner
// walls (sun from the west, 270 degrees), which the estimate must agree with.
TEST(SunAzimuth, HrscNanediFromTheImageAlone) {
  SKIP_WITHOUT_SHARED_DATA();
  const RasterDataset dataset =
      RasterDataset::Open(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png");
  CraterDetectorOptions detector;
  detector.min_diameter_px = 6.0;
  const SunAzimuthEstimate e = EstimateSunAzimuthInRaster(dataset, detector);
  std::printf("HRSC: estimated %.1f from %d votes of %d candidates, agreement %.2f\n",
              e.azimuth_deg, e.votes, e.candidates, e.agreement);
  RecordProperty("azimuth_deg", std::to_string(e.azimuth_deg));
  EXPECT_TRUE(e.reliable);
  EXPECT_LT(AngleBetweenDeg(e.azimuth_deg, 270.0), 30.0);
}

TEST(SunAzimuth, BadOptionsNameTheField) {
  SunAzimuthOptions options;
  options.min_agreement = 0.0;
  const std::string message =
      testing::ErrorMessageOf([&] { EstimateSunAzimuth(cv::Mat(8, 8, CV_32F), {}, options); });
  EXPECT_NE(message.find("SunAzimuthOptions.min_agreement"), std::string::npos) << message;
}

}  // namespace
}  // namespace areomap
