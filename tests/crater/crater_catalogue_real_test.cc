// The crater catalogue on the real CTX images of ../shared/data/craters-train/ctx-mc11e (2000 x
// 2000 px, about 6 m/px, no georeference), given made-up Mars georeferences: one image cut into
// overlapping crops, and the twelve images on an overlapping grid (issue 47's acceptance).
// Each image takes about 3 s to detect on 2 cores: label "long".
#include <chrono>
#include <cmath>
#include <fstream>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include "areomap/crater/crater_catalogue.h"
#include "areomap/crater/crater_catalogue_merge.h"
#include "areomap/crater/same_crater.h"
#include "areomap/map/crs.h"
#include "areomap/map/projection.h"
#include "test_support.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

constexpr double kGsd = 6.0;  // [m], CTX's

fs::path CtxImage(char letter) {
  return testing::SharedDataDir() / "craters-train" / "ctx-mc11e" /
         (std::string("MC11E-") + letter + ".png");
}

// The detector as `areomap craters` runs it, without the sun estimate: on a crop the estimate
// can be reliable where on the whole image it is not (or the other way), which switches the
// shading checks and changes the craters found; the merge is what these tests measure.
CraterImageOptions Options() {
  CraterImageOptions options;
  options.estimate_sun = false;
  return options;
}

// `image`'s pixels [col0, col0 + size) x [row0, row0 + size) as a GeoTIFF whose upper left
// corner lies at `corner` of `crs_wkt`.
void WriteCrop(const cv::Mat& image, const cv::Rect& window, const Eigen::Vector2d& corner,
               const std::string& crs_wkt, const fs::path& path) {
  GeoRaster raster;
  raster.bands = {image(window).clone()};
  raster.geotransform = GeoTransform::NorthUp(corner.x(), corner.y(), kGsd, kGsd);
  raster.crs_wkt = crs_wkt;
  WriteGeoTiff(path, raster);
}

struct Merged {
  std::vector<CraterCircle> craters;  // centre, diameter [m] in the common CRS
  std::string crs_wkt;
};

Merged ReadMergedGeoPackage(const fs::path& gpkg) {
  GDALAllRegister();
  GDALDatasetUniquePtr ds(GDALDataset::Open(gpkg.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  Merged merged;
  EXPECT_TRUE(ds) << gpkg;
  if (!ds) return merged;
  EXPECT_EQ(ds->GetLayerCount(), 1);
  OGRLayer* layer = ds->GetLayerByName("craters");
  EXPECT_NE(layer, nullptr);
  if (layer == nullptr || layer->GetSpatialRef() == nullptr) return merged;
  char* wkt = nullptr;
  layer->GetSpatialRef()->exportToWkt(&wkt);
  merged.crs_wkt = wkt;
  CPLFree(wkt);
  for (auto& f : *layer) {
    merged.craters.push_back({{f->GetFieldAsDouble("map_x"), f->GetFieldAsDouble("map_y")},
                              f->GetFieldAsDouble("diameter_m")});
  }
  return merged;
}

// Pairs of craters that are one crater by SameCraterEitherWay (a sweep along x).
int SameCraterPairs(std::vector<CraterCircle> craters) {
  std::sort(craters.begin(), craters.end(),
            [](const auto& a, const auto& b) { return a.center.x() < b.center.x(); });
  double largest = 0.0;
  for (const CraterCircle& c : craters) largest = std::max(largest, c.diameter);
  const double reach = SameCraterSearchRadius(largest);
  int pairs = 0;
  for (size_t i = 0; i < craters.size(); ++i) {
    for (size_t j = i + 1; j < craters.size(); ++j) {
      if (craters[j].center.x() - craters[i].center.x() > reach) break;
      pairs += SameCraterEitherWay(craters[i], craters[j]) ? 1 : 0;
    }
  }
  return pairs;
}

// Runs each image into dir/images/<folder>/ and merges them into dir.
CatalogueMergeSummary RunCatalogue(const std::vector<fs::path>& images, const fs::path& dir) {
  std::vector<fs::path> units;
  for (size_t i = 0; i < images.size(); ++i) {
    units.push_back(dir / "images" / CatalogueImageFolderName(static_cast<int>(i + 1), images[i]));
    const CatalogueImageRecord r = RunCraterCatalogueImage(images[i], units.back(), Options());
    EXPECT_TRUE(r.ok) << r.error;
  }
  return MergeCraterCatalogues(units, dir);
}

// One CTX image cut into 2 x 2 crops of 1100 px overlapping by 200 px: the merged catalogue has
// no crater twice, each crater of the whole image that lies inside an overlap (whole in every
// crop that holds it) once, and about as many craters as the whole image. The counts differ by
// the craters near the crops' inner edges: cut by an edge, one crop fits a part of the rim
// (another centre and diameter, or nothing) and the other crop may not see it as the same crater.
TEST(CtxCatalogue, OverlappingCropsOfOneImageGiveTheWholeImagesCratersOnce) {
  SKIP_WITHOUT_SHARED_DATA();
  const TempDir dir;
  const cv::Mat image = RasterDataset::Open(CtxImage('A')).ReadWindow(1, {0, 0, 2000, 2000});
  const std::string wkt = Crs::FromUserInput("IAU_2015:49910").Wkt();
  std::vector<fs::path> crops;
  for (const int row0 : {0, 900}) {
    for (const int col0 : {0, 900}) {
      crops.push_back(dir.path() /
                      ("MC11E-A_" + std::to_string(row0) + "_" + std::to_string(col0) + ".tif"));
      WriteCrop(image, {col0, row0, 1100, 1100}, {col0 * kGsd, -row0 * kGsd}, wkt, crops.back());
    }
  }
  WriteCrop(image, {0, 0, 2000, 2000}, {0.0, 0.0}, wkt, dir.path() / "MC11E-A.tif");
  const CatalogueMergeSummary s = RunCatalogue(crops, dir.path() / "crops");
  const CatalogueMergeSummary whole =
      RunCatalogue({dir.path() / "MC11E-A.tif"}, dir.path() / "whole");
  const Merged merged = ReadMergedGeoPackage(dir.path() / "crops" / "craters.gpkg");
  const Merged reference = ReadMergedGeoPackage(dir.path() / "whole" / "craters.gpkg");
  RecordProperty("crops_detected", s.detected);
  RecordProperty("crops_kept", s.kept);
  RecordProperty("whole_kept", whole.kept);
  ASSERT_EQ(static_cast<int>(merged.craters.size()), s.kept);
  EXPECT_GT(s.duplicates_removed, 50);  // the overlaps hold more than 100 craters
  EXPECT_EQ(SameCraterPairs(merged.craters), 0);
  EXPECT_NEAR(s.kept, whole.kept, 0.1 * whole.kept);
  // Pixel rows and columns 900-1100 are in two (or four) crops.
  int in_overlap = 0, once = 0;
  for (const CraterCircle& c : reference.craters) {
    const double col = c.center.x() / kGsd, row = -c.center.y() / kGsd, r = 0.5 * c.diameter / kGsd;
    const auto inside = [r](double v) { return v - r >= 900.0 && v + r <= 1100.0; };
    if (!inside(col) && !inside(row)) continue;
    ++in_overlap;
    int matches = 0;
    for (const CraterCircle& m : merged.craters) matches += SameCraterEitherWay(c, m) ? 1 : 0;
    EXPECT_LE(matches, 1) << c.center.transpose() << " D " << c.diameter;
    once += matches == 1 ? 1 : 0;
  }
  EXPECT_GT(in_overlap, 80);
  EXPECT_GE(once, 0.95 * in_overlap);
}

// The twelve CTX images on a 4 x 3 grid whose footprints (12 km) overlap their neighbours by
// 10 % (1.2 km); the bottom row in another CRS (central meridian 10 degrees east) so that the
// merge moves it into the first image's. One GeoPackage, a Mars CRS, no crater twice, one row
// per image.
TEST(CtxCatalogue, TwelveImagesOnAnOverlappingGridGiveOneGeoPackageWithoutDuplicates) {
  SKIP_WITHOUT_SHARED_DATA();
  const TempDir dir;
  const Body sphere = Body::MarsSphere();
  const std::string wkt = Crs::FromUserInput("IAU_2015:49910").Wkt();
  const MapProjection east = MapProjection::Equirectangular(sphere, 0.0, RadFromDeg(10.0));
  const double step = 0.9 * 2000 * kGsd;
  std::vector<fs::path> images;
  const std::string letters = "ABCDEFGHIJKL";
  for (size_t k = 0; k < letters.size(); ++k) {
    const int row = static_cast<int>(k / 4), col = static_cast<int>(k % 4);
    Eigen::Vector2d corner(col * step, -row * step);
    std::string crs = wkt;
    if (row == 2) {
      corner = east.Forward(MapProjection::Equirectangular(sphere, 0.0, 0.0).Inverse(corner));
      crs = east.Wkt();
    }
    const cv::Mat image =
        RasterDataset::Open(CtxImage(letters[k])).ReadWindow(1, {0, 0, 2000, 2000});
    images.push_back(dir.path() / (std::string("MC11E-") + letters[k] + ".tif"));
    WriteCrop(image, {0, 0, 2000, 2000}, corner, crs, images.back());
  }
  const auto start = std::chrono::steady_clock::now();
  const CatalogueMergeSummary s = RunCatalogue(images, dir.path());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  RecordProperty("detected", s.detected);
  RecordProperty("kept", s.kept);
  RecordProperty("duplicates_removed", s.duplicates_removed);
  RecordProperty("seconds", std::to_string(seconds));
  RecordProperty("merge_seconds", std::to_string(s.seconds));
  EXPECT_EQ(s.images_ok, 12);
  EXPECT_GT(s.detected, 12 * 100);
  // Unrelated images under the made-up overlaps: only chance coincidences there, and the images'
  // own near-duplicates, are the same crater.
  EXPECT_LT(s.duplicates_removed, 0.05 * s.detected);
  const Merged merged = ReadMergedGeoPackage(dir.path() / "craters.gpkg");
  ASSERT_EQ(static_cast<int>(merged.craters.size()), s.kept);
  EXPECT_TRUE(Crs::FromWkt(merged.crs_wkt, "craters.gpkg").Describe().is_mars);
  EXPECT_EQ(Crs::FromWkt(merged.crs_wkt, "craters.gpkg").Describe().name,
            "Mars (2015) - Sphere / Ocentric / Equirectangular, clon = 0");
  EXPECT_EQ(SameCraterPairs(merged.craters), 0);
  // The bottom row's craters lie in the first CRS: within the grid's extent.
  for (const CraterCircle& c : merged.craters) {
    ASSERT_GE(c.center.x(), -1.0);
    ASSERT_LE(c.center.x(), 3 * step + 2000 * kGsd + 1.0);
    ASSERT_LE(c.center.y(), 1.0);
    ASSERT_GE(c.center.y(), -(2 * step + 2000 * kGsd) - 1.0);
  }
  std::ifstream table(dir.path() / "images.csv");
  std::string line;
  std::getline(table, line);
  int rows = 0;
  while (std::getline(table, line)) {
    ++rows;
    EXPECT_NE(line.find(",ok,"), std::string::npos) << line;
  }
  EXPECT_EQ(rows, 12);
}

}  // namespace
}  // namespace areomap
