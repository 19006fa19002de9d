#include "areomap/crater/crater_raster.h"

#include <array>
#include <filesystem>
#include <fstream>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>
#include <tbb/task_arena.h>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_output.h"
#include "areomap/crater/crater_score.h"
#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/image_io.h"
#include "test_support.h"

namespace areomap {
namespace {

// Synthetic bowls lit from azimuth 90 (east): bright western wall, dark eastern wall, sharp
// rim. Cheap to draw at any size, so tiling can be exercised on a raster larger than a tile.
cv::Mat DrawBowls(int size, const std::vector<CraterCircle>& craters) {
  cv::Mat image(size, size, CV_32F, cv::Scalar(400.0));
  for (const CraterCircle& c : craters) {
    const double r = 0.5 * c.diameter;
    const int c0 = std::max(0, static_cast<int>(c.center.x() - r - 2));
    const int c1 = std::min(size - 1, static_cast<int>(c.center.x() + r + 2));
    const int r0 = std::max(0, static_cast<int>(c.center.y() - r - 2));
    const int r1 = std::min(size - 1, static_cast<int>(c.center.y() + r + 2));
    for (int y = r0; y <= r1; ++y) {
      for (int x = c0; x <= c1; ++x) {
        const double dx = x + 0.5 - c.center.x(), dy = y + 0.5 - c.center.y();
        const double rho = std::hypot(dx, dy) / r;
        if (rho >= 1.0) continue;
        // The wall slope grows towards the rim; the western wall faces the sun (east): bright.
        image.at<float>(y, x) = static_cast<float>(400.0 - 300.0 * (dx / r) * rho);
      }
    }
  }
  cv::GaussianBlur(image, image, cv::Size(), 0.7);
  cv::Mat noise(image.size(), CV_32F);
  cv::randn(noise, 0.0, 3.0);
  return image + noise;
}

// `image` written as a plain (not georeferenced) GeoTIFF at `path`, opened for windowed reads.
RasterDataset WritePlainGeoTiff(const std::filesystem::path& path, const cv::Mat& image) {
  std::filesystem::create_directories(path.parent_path());
  GeoRaster raster;
  raster.bands = {image};
  WriteGeoTiff(path, raster);
  return RasterDataset::Open(path);
}

// The same craters in the same order, bit for bit, as DetectCratersInRaster finds with one thread
// (taking the tiles one by one): the result does not depend on the order the tiles finish in.
void ExpectSameAsWithOneThread(const RasterDataset& dataset, const CraterDetectorOptions& options,
                               const std::vector<CraterDetection>& found) {
  std::vector<CraterDetection> one_thread;
  tbb::task_arena(1).execute(
      [&] { one_thread = DetectCratersInRaster(dataset, RimSource::kImage, options); });
  ASSERT_EQ(one_thread.size(), found.size());
  for (size_t i = 0; i < found.size(); ++i) {
    EXPECT_EQ(one_thread[i].ellipse.center, found[i].ellipse.center) << i;
    EXPECT_EQ(one_thread[i].ellipse.semi_major, found[i].ellipse.semi_major) << i;
    EXPECT_EQ(one_thread[i].ellipse.semi_minor, found[i].ellipse.semi_minor) << i;
    EXPECT_EQ(one_thread[i].ellipse.angle, found[i].ellipse.angle) << i;
    EXPECT_EQ(one_thread[i].confidence, found[i].confidence) << i;
  }
}

// Tiles of 400 px with 96 px overlap, so that a 1000 px raster has seams; every crater of these
// tests is >= 18 px across, so no upsampled level.
CraterDetectorOptions SmallTileOptions() {
  CraterDetectorOptions options;
  options.method = CraterMethod::kEdges;  // the edge pipeline's tiling (learned: its own test)
  options.sun_azimuth_deg = 90.0;
  options.tile_size = 400;
  options.tile_overlap = 96;
  options.min_diameter_px = 12.0;
  options.upsample_small_craters = false;
  return options;
}

TEST(DetectCratersInRaster, TilesAndOverviewFindSmallAndLargeCraters) {
  const int size = 1100;
  std::vector<CraterCircle> truth;
  // Small craters everywhere, including across tile borders (tile core 400 px).
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      truth.push_back(
          {{100.0 + 210.0 * i + 7.0 * j, 90.0 + 210.0 * j}, 18.0 + 3.0 * ((i + j) % 5)});
    }
  }
  truth.push_back({{550.0, 550.0}, 240.0});  // larger than the 96 px tile overlap
  // Keep the small ones off the big one.
  std::erase_if(truth, [](const CraterCircle& c) {
    return c.diameter < 100 && (c.center - Eigen::Vector2d(550, 550)).norm() < 150;
  });
  const auto dir = std::filesystem::temp_directory_path() / "areomap_crater_raster_test";
  const RasterDataset dataset = WritePlainGeoTiff(dir / "bowls.tif", DrawBowls(size, truth));
  const CraterDetectorOptions options = SmallTileOptions();
  int progress_calls = 0;
  const std::vector<CraterDetection> found =
      DetectCratersInRaster(dataset, RimSource::kImage, options, [&](double, std::string_view) {
        ++progress_calls;
        return true;
      });
  const std::vector<CraterCircle> circles = CirclesOf(found);
  const CraterScore score = ScoreCraters(truth, circles, {10.0, 1e9});
  for (size_t t = 0; t < truth.size(); ++t) {
    if (std::none_of(score.matches.begin(), score.matches.end(),
                     [&](auto m) { return m.first == static_cast<int>(t); })) {
      ADD_FAILURE() << "missed " << truth[t].center.transpose() << " D " << truth[t].diameter;
    }
  }
  EXPECT_GE(score.all.recall, 0.95);
  EXPECT_GE(score.all.precision, 0.95);
  EXPECT_GT(progress_calls, 4);
  bool big = false;
  for (const auto& [t, d] : score.matches) {
    if (truth[static_cast<size_t>(t)].diameter > 200) {
      big = true;
      EXPECT_LT(
          (circles[static_cast<size_t>(d)].center - truth[static_cast<size_t>(t)].center).norm(),
          1.5);
    }
  }
  EXPECT_TRUE(big);

  ExpectSameAsWithOneThread(dataset, options, found);

  // Outputs: not georeferenced -> CSV/JSON fine, GeoPackage refused with the reason.
  const CraterCatalog catalog = MakeCraterCatalog(found, dataset.info());
  EXPECT_FALSE(catalog.IsGeoreferenced());
  WriteCratersCsv(dir / "craters.csv", catalog);
  EXPECT_EQ(ReadCraterCsv(dir / "craters.csv").size(), found.size());
  EXPECT_THROW(WriteCratersGeoPackage(dir / "craters.gpkg", catalog), Error);
  EXPECT_FALSE(std::filesystem::exists(dir / "craters.gpkg"));
  std::filesystem::remove_all(dir);
}

TEST(DetectCratersInRaster, SmallCratersOnTheUpsampledLevelOfEveryTile) {
  // Bowls 10-14 px across (only the 2x upsampled level searches them), on a 3 x 3 tile grid and
  // across its seams: each tile's level and edges live in the tile's reused scratch. The walls
  // of such small bowls give arcs whose centres lie apart along the sun line: without grouping
  // them (GroupArcs) each wall was fitted as its own smaller circle (precision 0.77, recall 0.80).
  std::vector<CraterCircle> truth;
  for (int i = 0; i < 9; ++i) {
    for (int j = 0; j < 9; ++j) {
      truth.push_back({{60.0 + 120.0 * i + 3.0 * j, 55.0 + 120.0 * j}, 10.0 + (i + j) % 5});
    }
  }
  const auto dir = std::filesystem::temp_directory_path() / "areomap_crater_upsampled_test";
  const RasterDataset dataset = WritePlainGeoTiff(dir / "small.tif", DrawBowls(1100, truth));
  CraterDetectorOptions options = SmallTileOptions();
  options.min_diameter_px = 8.0;
  options.upsample_small_craters = true;
  const std::vector<CraterDetection> found =
      DetectCratersInRaster(dataset, RimSource::kImage, options);
  const CraterScore score = ScoreCraters(truth, CirclesOf(found), {8.0, 1e9});
  EXPECT_GE(score.all.recall, 0.95);
  EXPECT_GE(score.all.precision, 0.95);
  ExpectSameAsWithOneThread(dataset, options, found);
  // The upsampled level searched everywhere, not only around small full-resolution arcs: as
  // good, and the same fits but for one (the edges differ only by the thresholds' sampling and
  // float rounding, rim_edges.h).
  options.upsample_only_around_small_arcs = false;
  const std::vector<CraterDetection> everywhere =
      DetectCratersInRaster(dataset, RimSource::kImage, options);
  const CraterScore everywhere_score = ScoreCraters(truth, CirclesOf(everywhere), {8.0, 1e9});
  EXPECT_NEAR(everywhere_score.all.recall, score.all.recall,
              1.5 / static_cast<double>(truth.size()));
  EXPECT_NEAR(everywhere_score.all.precision, score.all.precision, 0.02);
  const CraterScore same = ScoreCraters(CirclesOf(everywhere), CirclesOf(found), {8.0, 1e9});
  size_t same_fits = 0;
  for (const auto& [e, f] : same.matches) {
    const double shift = (everywhere[static_cast<size_t>(e)].ellipse.center -
                          found[static_cast<size_t>(f)].ellipse.center)
                             .norm();
    if (shift < 0.1) ++same_fits;
  }
  EXPECT_GE(same_fits + 1, found.size());
  std::filesystem::remove_all(dir);
}

TEST(DetectCratersInRaster, CancellingStopsWithAnErrorAtAnyTile) {
  // 3 x 3 tiles and an overview: cancelled at the first tile, and at the last one, when every
  // tile has been searched and the overview has not.
  const auto dir = std::filesystem::temp_directory_path() / "areomap_crater_cancel_test";
  const RasterDataset dataset =
      WritePlainGeoTiff(dir / "bowls.tif", DrawBowls(1100, {{{550.0, 550.0}, 240.0}}));
  const CraterDetectorOptions options = SmallTileOptions();
  for (const int stop_at : {1, 9}) {
    int calls = 0;
    try {
      DetectCratersInRaster(dataset, RimSource::kImage, options,
                            [&](double, std::string_view) { return ++calls < stop_at; });
      ADD_FAILURE() << "not cancelled at progress call " << stop_at;
    } catch (const Error& error) {
      EXPECT_NE(std::string(error.what()).find("cancelled"), std::string::npos) << error.what();
    }
    EXPECT_GE(calls, stop_at);
  }
  std::filesystem::remove_all(dir);
}

TEST(DetectCratersInRaster, CratersOnTileSeamsAreFoundOnceAsOnTheWholeRaster) {
  // Tile cores of 400 px: seams at 400 and 800. Craters centred a few pixels either side of a
  // seam are kept by exactly one tile (each tile fits only what may end in its core); their
  // fits agree with those on the whole raster.
  const int size = 1000;
  const std::array<double, 6> offsets = {-6.0, -2.0, -0.4, 0.4, 2.0, 6.0};
  std::vector<CraterCircle> truth;
  for (size_t k = 0; k < offsets.size(); ++k) {
    const double step = 55.0 * static_cast<double>(k);
    truth.push_back({{400.0 + offsets[k], 80.0 + step}, 18.0 + 2.0 * static_cast<double>(k)});
    truth.push_back({{470.0 + step, 800.0 + offsets[k]}, 28.0 - 2.0 * static_cast<double>(k)});
  }
  truth.push_back({{801.5, 398.5}, 24.0});  // on a tile corner
  truth.push_back({{399.0, 801.0}, 20.0});
  const cv::Mat image = DrawBowls(size, truth);
  const auto dir = std::filesystem::temp_directory_path() / "areomap_crater_seam_test";
  const RasterDataset dataset = WritePlainGeoTiff(dir / "seams.tif", image);
  CraterDetectorOptions options = SmallTileOptions();
  options.max_diameter_px = 60.0;  // tiles only, no overview
  const std::vector<CraterDetection> tiled =
      DetectCratersInRaster(dataset, RimSource::kImage, options);
  const std::vector<CraterDetection> whole = DetectCraters(image, RimSource::kImage, options);
  const auto near = [](const std::vector<CraterDetection>& found, const CraterCircle& t) {
    std::vector<const CraterDetection*> hits;
    for (const CraterDetection& d : found) {
      if ((d.ellipse.center - t.center).norm() < 0.25 * t.diameter) hits.push_back(&d);
    }
    return hits;
  };
  for (const CraterCircle& t : truth) {
    const auto in_tiles = near(tiled, t);
    const auto in_whole = near(whole, t);
    ASSERT_EQ(in_tiles.size(), 1u) << "at " << t.center.transpose();
    ASSERT_EQ(in_whole.size(), 1u) << "at " << t.center.transpose();
    // The same pixels; only the tiles' automatic edge thresholds differ from the whole
    // raster's, which moves a rim fit by a small fraction of a pixel.
    EXPECT_LT((in_tiles[0]->ellipse.center - in_whole[0]->ellipse.center).norm(), 0.1)
        << "at " << t.center.transpose();
    EXPECT_NEAR(in_tiles[0]->Diameter(), in_whole[0]->Diameter(), 0.01 * t.diameter)
        << "at " << t.center.transpose();
  }
  EXPECT_EQ(tiled.size(), truth.size());
  std::filesystem::remove_all(dir);
}

TEST(CraterOutput, GeoPackageCarriesTheMarsCrsAndLatLon) {
  RasterInfo info;
  info.path = "synthetic.tif";
  info.width = info.height = 100;
  // 10 m pixels, equirectangular with standard parallel 14.5 S, centre meridian 175.5 E: map
  // (0, 0) is on the equator at 175.5 E.
  info.geotransform = GeoTransform::NorthUp(-500.0, 500.0, 10.0, 10.0);
  info.crs_wkt =
      ProjectedCrsWkt(Body::Mars2000(), "Equirectangular",
                      {{"center_lat", RadFromDeg(-14.5)}, {"center_lon", RadFromDeg(175.5)}});
  CraterDetection d;
  d.ellipse = Ellipse{{50.0, 50.0}, 8.0, 6.0, 0.3};
  const CraterCatalog catalog = MakeCraterCatalog({d}, info);
  ASSERT_TRUE(catalog.IsGeoreferenced());
  EXPECT_DOUBLE_EQ(catalog.pixel_size_m, 10.0);
  const CatalogCrater& c = catalog.craters.at(0);
  EXPECT_DOUBLE_EQ(c.semi_major_m, 80.0);
  ASSERT_TRUE(c.lat_deg && c.lon_deg);
  EXPECT_NEAR(*c.lat_deg, 0.0, 1e-9);  // the pixel centre (50, 50) is map (0, 0)
  EXPECT_NEAR(*c.lon_deg, 175.5, 1e-6);
  const auto dir = std::filesystem::temp_directory_path() / "areomap_crater_gpkg_test";
  std::filesystem::create_directories(dir);
  WriteCratersGeoPackage(dir / "craters.gpkg", catalog);
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open((dir / "craters.gpkg").c_str(), GDAL_OF_VECTOR));
  ASSERT_TRUE(ds);
  OGRLayer* layer = ds->GetLayerByName("craters");
  ASSERT_NE(layer, nullptr);
  EXPECT_EQ(layer->GetFeatureCount(), 1);
  ASSERT_NE(layer->GetSpatialRef(), nullptr);
  EXPECT_NEAR(layer->GetSpatialRef()->GetSemiMajor(), Body::Mars2000().a, 30000.0);
  std::unique_ptr<OGRFeature> feature(layer->GetNextFeature());
  ASSERT_TRUE(feature);
  EXPECT_NEAR(feature->GetFieldAsDouble("lon_deg"), 175.5, 1e-6);
  OGREnvelope envelope;
  feature->GetGeometryRef()->getEnvelope(&envelope);
  EXPECT_NEAR(envelope.MaxX - envelope.MinX, 2 * 80.0, 40.0);  // rotated 8 x 6 px ellipse
  ds.reset();
  std::filesystem::remove_all(dir);
}

TEST(ScoreCraters, AppliesTheMatchingRule) {
  const std::vector<CraterCircle> truth = {{{0, 0}, 20}, {{100, 0}, 20}, {{200, 0}, 20}};
  const std::vector<CraterCircle> det = {
      {{4.9, 0}, 20},    // 4.9 < 0.5 x 10: match
      {{105.1, 0}, 20},  // too far
      {{200, 0}, 26.5},  // ratio 1.325 > 1.3: no match
      {{0.5, 0}, 21}};   // second detection of the first crater: false positive
  const CraterScore s = ScoreCraters(truth, det, {0.0, 1e9});
  EXPECT_EQ(s.all.matched_truth, 1);
  EXPECT_DOUBLE_EQ(s.all.recall, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(s.all.precision, 0.25);
  ASSERT_EQ(s.matches.size(), 1u);
  EXPECT_EQ(s.matches[0].second, 3);  // the closer of the two candidates
}

TEST(WriteScoreOverlay, MatchedGreenMissedRedFalseAlarmYellow) {
  // Uniform grey 200 x 100 image; RGB in file order. Rims are drawn at the circle radius
  // (truth) and 2 px outside it (false alarms), so probe pixels on those circles.
  const cv::Mat image(100, 200, CV_32F, cv::Scalar(10.0));
  const std::vector<CraterCircle> truth = {{{50.5, 50.5}, 40}, {{150.5, 50.5}, 40}};
  const std::vector<CraterCircle> det = {{{50.5, 50.5}, 40}, {{150.5, 20.5}, 10}};
  const CraterScore score = ScoreCraters(truth, det, {8.0, 1e9});
  ASSERT_EQ(score.matches.size(), 1u);
  areomap::testing::TempDir dir;
  const auto path = dir.path() / "overlay.png";
  WriteScoreOverlay(path, image, truth, det, score, 8.0);
  const cv::Mat rgb = ReadImage(path);
  ASSERT_EQ(rgb.type(), CV_8UC3);
  const auto pixel = [&](int x, int y) { return rgb.at<cv::Vec3b>(y, x); };
  EXPECT_GT(pixel(70, 50)[1], 150);  // matched truth rim: green
  EXPECT_LT(pixel(70, 50)[0], 100);
  EXPECT_GT(pixel(170, 50)[0], 150);  // missed truth rim: red
  EXPECT_LT(pixel(170, 50)[1], 100);
  const cv::Vec3b alarm = pixel(157, 20);  // false alarm, radius 5 + 2 px: yellow
  EXPECT_GT(alarm[0], 150);
  EXPECT_GT(alarm[1], 150);
  EXPECT_LT(alarm[2], 100);
}

TEST(CirclesOf, TakesTheCentreAndTheRimDiameterAPlusB) {
  const Ellipse e{Eigen::Vector2d(3.0, -2.0), 5.0, 3.0, 0.4};
  CraterDetection d;
  d.ellipse = e;
  for (const std::vector<CraterCircle>& circles : {CirclesOf({e}), CirclesOf({d})}) {
    ASSERT_EQ(circles.size(), 1u);
    EXPECT_EQ(circles[0].center, e.center);
    EXPECT_EQ(circles[0].diameter, 8.0);
  }
  EXPECT_TRUE(CirclesOf(std::vector<Ellipse>{}).empty());
}

TEST(ReadCraterCsv, NamesFileAndLineOfBadInput) {
  const auto path = std::filesystem::temp_directory_path() / "areomap_bad_craters.csv";
  std::ofstream(path) << "x_px,y_px,diameter_px\n1,2,3\n4,five,6\n";
  try {
    ReadCraterCsv(path);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "x,y,d\n1,2,3\n";
  EXPECT_THROW(ReadCraterCsv(path), Error);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace areomap
