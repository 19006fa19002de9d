// Rover DTMs from simulated stereo clouds (the generator's truth scene, viewshed, eq. 4.3 noise)
// compared with the scene's true heights.
#include "areomap/map/dtm.h"

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

#include <gtest/gtest.h>

#include "areomap/map/raster.h"
#include "areomap/samples/orbital.h"
#include "areomap/samples/simulated_points.h"
#include "test_support.h"

namespace areomap {
namespace {

// A scene without rocks (relief the points resolve: the test is about the noise model) and the
// mission georeference the generator would give it.
struct SimulatedMission {
  Scene scene;
  SceneGeoreference georef;
  MapFrame map;

  explicit SimulatedMission(int max_rocks = 0)
      : scene([&] {
          SceneOptions o;
          o.half_extent_m = 96.0;
          o.crater_count = 3;
          o.crater_max_diameter_m = 40.0;
          o.max_rocks = max_rocks;
          o.rock_path = {{-40.0, 0.0}, {40.0, 0.0}};
          o.seed = 11;
          return o;
        }()),
        georef{Body::Mars2000(),
               {RadFromDeg(-14.5692), RadFromDeg(175.4729), scene.GroundHeightAt(0.0, 0.0)}},
        map(MapFrame::LocalEquirectangular(georef.body, georef.origin)) {}

  // The site at ENU (east, north): its cloud and its pose in the mission (site 0's frame).
  SiteGeoreference Site(const Eigen::Vector2d& site_enu) const {
    const Eigen::Vector3d origin_in_enu(
        site_enu.x(), site_enu.y(),
        scene.GroundHeightAt(site_enu.x(), site_enu.y()) - georef.origin.h);
    const Rigid3d mission_from_site(Eigen::Quaterniond::Identity(), SiteFromEnu() * origin_in_enu);
    return SiteGeoreference::InMission(georef.body, georef.origin, mission_from_site);
  }

  // True height and ENU position under a map cell centre at height z.
  std::pair<double, Eigen::Vector2d> Truth(const Eigen::Vector2d& xy, double z) const {
    const Eigen::Vector3d enu = georef.EnuFromMbf() * map.MbfFromMap({xy.x(), xy.y(), z});
    return {scene.HeightAt(enu.x(), enu.y()), enu.head<2>()};
  }
};

PointCloud SimulatedCloud(const SimulatedMission& m, const Eigen::Vector2d& site_enu, int site,
                          double azimuth_min_deg, double azimuth_max_deg) {
  SimulatedPointsOptions o;
  o.azimuth_min_deg = azimuth_min_deg;
  o.azimuth_max_deg = azimuth_max_deg;
  o.max_range_m = 25.0;
  o.seed = 7 + static_cast<uint32_t>(site);
  return SimulateSitePointCloud(m.scene, site_enu, site, o);
}

struct BinStats {
  double squared_error = 0.0;
  double squared_sigma = 0.0;
  int cells = 0;
  int area_cells = 0;  // Cells of the bin's annulus sector (for coverage).
};

// Range bins of the issue: 0-5, 5-10, 10-15, 15-25 m.
constexpr std::array<double, 5> kBinEdges{0.0, 5.0, 10.0, 15.0, 25.0};

std::array<BinStats, 4> ErrorByRange(const SimulatedMission& m, const Dtm& dtm,
                                     const Eigen::Vector2d& site_enu, double min_range,
                                     double azimuth_min_deg, double azimuth_max_deg) {
  std::array<BinStats, 4> bins{};
  const GriddedLayers& l = dtm.layers;
  for (int row = 0; row < l.grid.height; ++row) {
    for (int col = 0; col < l.grid.width; ++col) {
      const float z = l.elevation.at<float>(row, col);
      const auto [truth, enu] =
          m.Truth(l.grid.CellCenter(col, row), std::isfinite(z) ? z : m.georef.origin.h);
      const Eigen::Vector2d d = enu - site_enu;
      const double range = d.norm();
      double azimuth = DegFromRad(std::atan2(d.x(), d.y()));
      if (azimuth < 0.0) azimuth += 360.0;
      if (range < min_range || range >= kBinEdges.back() || azimuth < azimuth_min_deg ||
          azimuth > azimuth_max_deg) {
        continue;
      }
      const size_t bin = static_cast<size_t>(
          std::upper_bound(kBinEdges.begin(), kBinEdges.end(), range) - kBinEdges.begin() - 1);
      ++bins[bin].area_cells;
      if (!std::isfinite(z)) continue;
      const double sigma = l.sigma.at<float>(row, col);
      bins[bin].squared_error += (z - truth) * (z - truth);
      bins[bin].squared_sigma += sigma * sigma;
      ++bins[bin].cells;
    }
  }
  return bins;
}

// The check: per range bin the RMS error against truth lies within 1.5x of the RMS of
// the propagated sigma (eq. 4.3 through the TIN), both ways; coverage is printed.
TEST(Dtm, TinErrorMatchesPropagatedSigmaPerRangeBin) {
  const SimulatedMission m;
  const Eigen::Vector2d site_enu(10.0, -5.0);
  const PointCloud cloud = SimulatedCloud(m, site_enu, 0, 0.0, 180.0);
  DtmOptions options;
  options.posting_m = 0.1;
  const Dtm dtm = MakeDtm({{&cloud, m.Site(site_enu)}}, m.map, options);
  const auto bins = ErrorByRange(m, dtm, site_enu, 2.0, 0.0, 180.0);
  for (size_t b = 0; b < bins.size(); ++b) {
    const BinStats& s = bins[b];
    ASSERT_GT(s.cells, 100) << "bin " << b;
    const double rms_error = std::sqrt(s.squared_error / s.cells);
    const double rms_sigma = std::sqrt(s.squared_sigma / s.cells);
    std::printf(
        "range %4.0f-%2.0f m: %7d cells, coverage %5.1f %%, RMS error %.4f m, RMS sigma %.4f m, "
        "ratio %.2f\n",
        kBinEdges[b], kBinEdges[b + 1], s.cells, 100.0 * s.cells / s.area_cells, rms_error,
        rms_sigma, rms_error / rms_sigma);
    EXPECT_LT(rms_error, 1.5 * rms_sigma) << "bin " << b;
    EXPECT_GT(rms_error, rms_sigma / 1.5) << "bin " << b;
  }
}

// Two overlapping sites merged with inverse-variance weights: coverage is the union, and where
// both see the ground the merged error is no worse than the better site's sigma allows.
TEST(Dtm, MergesSitesWithInverseVarianceWeights) {
  const SimulatedMission m;
  const Eigen::Vector2d a(0.0, 0.0), b(12.0, 0.0);
  const PointCloud cloud_a = SimulatedCloud(m, a, 0, 45.0, 135.0);
  const PointCloud cloud_b = SimulatedCloud(m, b, 1, 225.0, 315.0);
  DtmOptions options;
  options.posting_m = 0.2;
  const Dtm merged = MakeDtm({{&cloud_a, m.Site(a)}, {&cloud_b, m.Site(b)}}, m.map, options);
  const Dtm only_a = MakeDtm({{&cloud_a, m.Site(a)}}, m.map, options);
  const Dtm only_b = MakeDtm({{&cloud_b, m.Site(b)}}, m.map, options);
  EXPECT_GT(merged.layers.known_cells, only_a.layers.known_cells);
  EXPECT_GT(merged.layers.known_cells, only_b.layers.known_cells);
  EXPECT_LE(merged.layers.known_cells, only_a.layers.known_cells + only_b.layers.known_cells);
  double squared_error = 0.0, squared_sigma = 0.0;
  int cells = 0;
  const GriddedLayers& l = merged.layers;
  for (int row = 0; row < l.grid.height; ++row) {
    for (int col = 0; col < l.grid.width; ++col) {
      const float z = l.elevation.at<float>(row, col);
      if (!std::isfinite(z)) continue;
      const double truth = m.Truth(l.grid.CellCenter(col, row), z).first;
      squared_error += (z - truth) * (z - truth);
      squared_sigma += l.sigma.at<float>(row, col) * l.sigma.at<float>(row, col);
      ++cells;
    }
  }
  ASSERT_GT(cells, 1000);
  const double ratio = std::sqrt(squared_error / squared_sigma);
  std::printf("merged: %d cells, RMS error / RMS sigma = %.2f\n", cells, ratio);
  EXPECT_LT(ratio, 1.5);
  EXPECT_GT(ratio, 1.0 / 1.5);
  // The counts add up.
  EXPECT_EQ(cv::sum(l.count)[0], cloud_a.points.size() + cloud_b.points.size());
}

TEST(Dtm, WritesAGeoTiffWithTheMarsCrsAndNodata) {
  const SimulatedMission m;
  const PointCloud cloud = SimulatedCloud(m, {0.0, 0.0}, 0, 80.0, 100.0);
  DtmOptions options;
  options.posting_m = 0.25;
  const Dtm dtm = MakeDtm({{&cloud, m.Site({0.0, 0.0})}}, m.map, options);
  testing::TempDir dir;
  WriteDtm(dir.path() / "dtm.tif", dtm);
  const RasterDataset dataset = RasterDataset::Open(dir.path() / "dtm.tif");
  EXPECT_EQ(dataset.info().band_count, 4);
  EXPECT_EQ(dataset.info().width, dtm.layers.grid.width);
  ASSERT_TRUE(dataset.info().nodata.has_value());
  EXPECT_TRUE(std::isnan(*dataset.info().nodata));
  const CrsDescription crs = Crs::FromWkt(dataset.info().crs_wkt, "dtm.tif").Describe();
  EXPECT_TRUE(crs.is_mars);
  EXPECT_TRUE(crs.is_projected);
  const cv::Mat elevation = dataset.ReadWindowFloat(1, dataset.FullWindow());
  int known = 0;
  for (int row = 0; row < elevation.rows; ++row) {
    for (int col = 0; col < elevation.cols; ++col) {
      known += std::isfinite(elevation.at<float>(row, col)) ? 1 : 0;
    }
  }
  EXPECT_EQ(known, dtm.layers.known_cells);
  EXPECT_LT(known, elevation.rows * elevation.cols);  // A 20 degree wedge leaves nodata.
}

TEST(Dtm, RejectsEmptyAndNonFiniteClouds) {
  const SimulatedMission m;
  PointCloud empty;
  empty.frame = "SITE_FRAME site 4";
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MakeDtm({{&empty, m.Site({0.0, 0.0})}}, m.map, DtmOptions{});
            }).find("SITE_FRAME site 4"),
            std::string::npos);
  PointCloud bad = SimulatedCloud(m, {0.0, 0.0}, 0, 80.0, 82.0);
  bad.points[3].position.y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MakeDtm({{&bad, m.Site({0.0, 0.0})}}, m.map, DtmOptions{});
            }),
            "");
  EXPECT_NE(testing::ErrorMessageOf([&] { MakeDtm({}, m.map, DtmOptions{}); }).find("no point"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap
