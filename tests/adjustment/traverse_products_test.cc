#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/adjustment/traverse_adjustment.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/projection.h"
#include "areomap/map/raster.h"
#include "bundle_simulation.h"
#include "test_support.h"

namespace areomap {
namespace {

using testing::SimulatedNetwork;
using testing::SimulatedNetworkOptions;
using testing::SimulateNetwork;

std::filesystem::path TempDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("areomap_products_" + name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::vector<Eigen::Vector3d> TruePositions(const SimulatedNetwork& net) {
  std::vector<Eigen::Vector3d> out;
  for (const Rigid3d& t : net.truth) out.push_back(t.translation);
  return out;
}

TEST(TraverseAnchoring, ErrorEllipseAxesAndAzimuth) {
  ErrorEllipse e = HorizontalErrorEllipse(Eigen::Vector2d(4.0, 1.0).asDiagonal());
  EXPECT_NEAR(e.semi_major_m, 2.0, 1e-12);
  EXPECT_NEAR(e.semi_minor_m, 1.0, 1e-12);
  EXPECT_NEAR(std::min(e.azimuth_rad, std::numbers::pi - e.azimuth_rad), 0.0, 1e-12);  // North.
  e = HorizontalErrorEllipse(Eigen::Vector2d(1.0, 9.0).asDiagonal());
  EXPECT_NEAR(e.semi_major_m, 3.0, 1e-12);
  EXPECT_NEAR(e.azimuth_rad, std::numbers::pi / 2, 1e-12);  // East.
  // Major axis toward north-east: equal variances, positive correlation.
  Eigen::Matrix2d c;
  c << 2.0, 1.0, 1.0, 2.0;
  e = HorizontalErrorEllipse(c);
  EXPECT_NEAR(e.semi_major_m, std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(e.azimuth_rad, std::numbers::pi / 4, 1e-12);
}

TEST(TraverseAnchoring, SitesInMbfAndGeographicAgreeWithGeodesy) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 4;
  const SimulatedNetwork net = SimulateNetwork(options);
  const BundleResult result = AdjustBundle(net.input);
  const AnchoredTraverse anchored = AnchorTraverse(net.input, result, TruePositions(net));
  const Rigid3d traverse_from_mbf = SiteFromMbf(net.input.body, net.input.origin);
  for (const AnchoredSite& s : anchored.sites) {
    EXPECT_LT((traverse_from_mbf * s.position_mbf - s.position_in_traverse).norm(), 1e-6);
    const Eigen::Vector3d back = MbfFromGeographic(net.input.body, s.geographic);
    EXPECT_LT((back - s.position_mbf).norm(), 1e-6);
    // Heights: the traverse frame's z is down from site 0's ground (curvature: millimetres).
    EXPECT_NEAR(s.geographic.h, net.input.origin.h - s.position_in_traverse.z(), 0.01);
  }
  ASSERT_EQ(anchored.legs.size(), 3u);
  EXPECT_TRUE(std::isfinite(anchored.legs[0].initial_re));
  EXPECT_GT(anchored.legs[0].predicted_re, 0.0);
}

TEST(BundleIo, JsonRoundTripGivesTheSameAdjustment) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 5;
  options.control_points_per_site = 1;
  options.pixel_observations = true;
  const SimulatedNetwork net = SimulateNetwork(options);
  ASSERT_FALSE(net.input.image_observations.empty());
  const std::filesystem::path dir = TempDir("io");
  WriteFileAtomically(dir / "network.json",
                      BundleInputToJson(net.input, TruePositions(net)).dump(1));
  const BundleInputFile file = ReadBundleInput({dir / "network.json"});
  ASSERT_EQ(file.truth.size(), 5u);
  EXPECT_EQ(file.input.tie_points.size(), net.input.tie_points.size());
  EXPECT_EQ(file.input.image_observations.size(), net.input.image_observations.size());
  const BundleResult a = AdjustBundle(net.input);
  const BundleResult b = AdjustBundle(file.input);
  for (size_t s = 0; s < a.sites.size(); ++s) {
    EXPECT_LT((a.sites[s].adjusted.translation - b.sites[s].adjusted.translation).norm(), 1e-6);
  }
  EXPECT_NEAR(a.sigma0, b.sigma0, 1e-6);

  // The same file given twice, and a point id a second file repeats, are named where they are.
  const std::string twice = testing::ErrorMessageOf([&] {
    ReadBundleInput({dir / "network.json", dir / "." / "network.json"});
  });
  EXPECT_NE(twice.find("network.json: given twice (as input 1 and 2)"), std::string::npos) << twice;
  nlohmann::json extra = {{"control_points", ControlPointsToJson({net.input.control_points[0]})}};
  WriteFileAtomically(dir / "extra.json", extra.dump());
  const std::string repeated = testing::ErrorMessageOf([&] {
    ReadBundleInput({dir / "network.json", dir / "extra.json"});
  });
  EXPECT_NE(repeated.find("extra.json: control_points id '" + net.input.control_points[0].id +
                          "' is already defined in " + (dir / "network.json").string()),
            std::string::npos)
      << repeated;
  std::filesystem::remove_all(dir);
}

// Integers outside int are errors naming the field, not wrapped (4294967297 read as site 1).
TEST(BundleIo, SiteIndexBeyondIntIsAnErrorNotAWrappedSite) {
  const std::filesystem::path dir = TempDir("int_range");
  WriteFileAtomically(dir / "net.json", R"({"origin": {"lat_deg": 0, "lon_deg": 0, "h_m": 0},
      "sites": [{"site": 0, "position_m": [0, 0, 0]}, {"site": 4294967297, "position_m": [1, 0, 0]}]})");
  const std::string message = testing::ErrorMessageOf([&] { ReadBundleInput({dir / "net.json"}); });
  EXPECT_NE(
      message.find("net.json: sites[1].site: expected an integer in [-2147483648, 2147483647]"),
      std::string::npos)
      << message;
  std::filesystem::remove_all(dir);
}

// Found by fuzz/adjust_json_fuzzer: a number beyond double escaped as json::out_of_range.
TEST(BundleIo, NumberBeyondDoubleIsNotValidJson) {
  const std::filesystem::path dir = TempDir("overflow");
  WriteFileAtomically(dir / "net.json", R"({"origin": {"lat_deg": 1e99999}})");
  const std::string message = testing::ErrorMessageOf([&] { ReadBundleInput({dir / "net.json"}); });
  EXPECT_NE(message.find("net.json: not valid JSON: "), std::string::npos) << message;
  EXPECT_NE(
      testing::ErrorMessageOf([&] { ReadTiePoints(dir / "net.json"); }).find("not valid JSON"),
      std::string::npos);
  std::filesystem::remove_all(dir);
}

// An orbital image around the origin: equirectangular on the local sphere, 2 m pixels.
std::filesystem::path WriteOrbitalImage(const BundleInput& input,
                                        const std::filesystem::path& dir) {
  const MapProjection projection =
      MapProjection::Equirectangular(input.body, input.origin.lat, input.origin.lon,
                                     EquirectangularRadius::kLocalAtCenterLatitude);
  const Eigen::Vector2d center = projection.Forward(input.origin);
  GeoRaster raster;
  const int size = 900;
  const double gsd = 2.0;
  cv::Mat band(size, size, CV_16U);
  for (int r = 0; r < size; ++r) {
    for (int c = 0; c < size; ++c) {
      band.at<uint16_t>(r, c) = static_cast<uint16_t>(300 + 200 * ((r / 20 + c / 20) % 2) + r / 3);
    }
  }
  raster.bands = {band};
  raster.geotransform =
      GeoTransform::NorthUp(center.x() - size * gsd / 2, center.y() + size * gsd / 2, gsd, gsd);
  raster.crs_wkt = projection.Wkt();
  WriteGeoTiff(dir / "orbital.tif", raster);
  return dir / "orbital.tif";
}

TEST(TraverseAdjustment, WritesEveryProductForATraverseWithControl) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 20;
  options.control_points_per_site = 2;
  const SimulatedNetwork net = SimulateNetwork(options);
  const std::filesystem::path dir = TempDir("run");
  WriteFileAtomically(dir / "network.json",
                      BundleInputToJson(net.input, TruePositions(net)).dump());
  TraverseAdjustmentOptions run;
  run.orbital_image = WriteOrbitalImage(net.input, dir);
  const std::filesystem::path out = dir / "out";
  std::filesystem::create_directories(out);
  const nlohmann::json summary = AdjustTraverse({dir / "network.json"}, out, run);
  EXPECT_EQ(summary["sites"], 20);
  EXPECT_LE(summary["adjusted_end_error_m"].get<double>(), 0.5);
  for (const char* name : {"adjustment.json", "report.txt", "sites.csv", "legs.csv",
                           "traverse.gpkg", "traverse_map.png"}) {
    EXPECT_TRUE(std::filesystem::exists(out / name)) << name;
  }
  // CSV: a header and one row per site / leg.
  const auto lines = [](const std::filesystem::path& p) {
    std::ifstream in(p);
    int n = 0;
    for (std::string line; std::getline(in, line);) ++n;
    return n;
  };
  EXPECT_EQ(lines(out / "sites.csv"), 21);
  EXPECT_EQ(lines(out / "legs.csv"), 20);
  // GeoPackage: five layers in a Mars geographic CRS, one point and one ellipse per site.
  GDALAllRegister();
  std::unique_ptr<GDALDataset> gpkg(
      GDALDataset::Open((out / "traverse.gpkg").c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  ASSERT_TRUE(gpkg);
  EXPECT_EQ(gpkg->GetLayerCount(), 5);
  EXPECT_EQ(gpkg->GetLayerByName("sites")->GetFeatureCount(), 20);
  EXPECT_EQ(gpkg->GetLayerByName("error_ellipses")->GetFeatureCount(), 20);
  const OGRSpatialReference* srs = gpkg->GetLayerByName("sites")->GetSpatialRef();
  ASSERT_NE(srs, nullptr);
  EXPECT_NEAR(srs->GetSemiMajor(), 3396190.0, 1.0);
  // Traverse map: the three tracks are drawn in their colours (file order RGB).
  const cv::Mat map = ReadImage(out / "traverse_map.png");
  ASSERT_EQ(map.channels(), 3);
  int red = 0, green = 0, blue = 0;
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const cv::Vec3b p = map.at<cv::Vec3b>(r, c);
      red += p[0] > 180 && p[1] < 80 && p[2] < 80;
      green += p[1] > 160 && p[0] < 100 && p[2] < 100;
      blue += p[2] > 180 && p[0] < 80;
    }
  }
  EXPECT_GT(red, 100);
  EXPECT_GT(green, 100);
  EXPECT_GT(blue, 0);  // Mostly under the adjusted track: with control they agree to 0.5 m.
  if (std::getenv("AREOMAP_KEEP_TEST_OUTPUT") == nullptr) std::filesystem::remove_all(dir);
}

TEST(TraverseAdjustment, RockTieVarianceFactorScalesTheRockTies) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 8;
  options.control_points_per_site = 1;
  const SimulatedNetwork net = SimulateNetwork(options);
  ASSERT_FALSE(net.input.tie_points.empty());
  const std::filesystem::path dir = TempDir("tie_factor");
  WriteFileAtomically(dir / "network.json",
                      BundleInputToJson(net.input, TruePositions(net)).dump());
  const auto adjust = [&](double factor) {
    TraverseAdjustmentOptions run;
    run.rock_tie_variance_factor = factor;
    const std::filesystem::path out = dir / ("f" + std::to_string(factor));
    std::filesystem::create_directories(out);
    return AdjustTraverse({dir / "network.json"}, out, run);
  };
  const nlohmann::json as_written = adjust(1.0);
  const nlohmann::json inflated = adjust(4.0);
  EXPECT_EQ(inflated["rock_tie_variance_factor"].get<double>(), 4.0);
  // The ties' share of the chi-square drops by 4, so sigma0 drops (the priors' and control
  // points' share is unchanged), and the sites' sigmas grow.
  EXPECT_LT(inflated["sigma0"].get<double>(), as_written["sigma0"].get<double>());
  EXPECT_GT(inflated["largest_horizontal_sigma_m"].get<double>(),
            as_written["largest_horizontal_sigma_m"].get<double>());
  EXPECT_THROW(adjust(0.0), Error);
  if (std::getenv("AREOMAP_KEEP_TEST_OUTPUT") == nullptr) std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace areomap
