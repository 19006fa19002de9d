// The crater catalogue over many images: the shared same-crater rule, one image's unit, the list
// file, and the merge on catalogues of known craters (crater_catalogue.h,
// crater_catalogue_merge.h).
#include <cmath>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include "areomap/crater/crater_catalogue.h"
#include "areomap/crater/crater_catalogue_merge.h"
#include "areomap/crater/crater_output.h"
#include "areomap/crater/same_crater.h"
#include "areomap/map/crs.h"
#include "areomap/map/projection.h"
#include "crater_scene.h"
#include "test_support.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using testing::ErrorMessageOf;
using testing::TempDir;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A crater as a detector reports it, in pixels.
CraterDetection Rim(Eigen::Vector2d center_px, double diameter_px, double sigma_px,
                    bool partial = false, bool rim_fitted = true) {
  CraterDetection d;
  d.ellipse = {center_px, 0.5 * diameter_px, 0.5 * diameter_px, 0.0};
  d.center_x_sigma = d.center_y_sigma = sigma_px;
  d.partial = partial;
  d.rim_fitted = rim_fitted;
  return d;
}

// An image folder as RunCraterCatalogueImage leaves it for `found` on a raster with `gt` and
// `crs_wkt`.
fs::path WriteImageFolder(const fs::path& dir, const std::string& image,
                          const std::vector<CraterDetection>& found, const GeoTransform& gt,
                          const std::string& crs_wkt) {
  fs::create_directories(dir);
  RasterInfo info;
  info.path = image;
  info.geotransform = gt;
  info.crs_wkt = crs_wkt;
  WriteCratersGeoPackage(dir / "craters.gpkg", MakeCraterCatalog(found, info));
  CatalogueImageRecord record;
  record.image = image;
  record.ok = true;
  record.craters = static_cast<int>(found.size());
  WriteCatalogueImageRecord(dir, record);
  return dir;
}

// Rows of the merged craters.gpkg: source folder and source id of each crater, its diameter_m.
struct MergedCrater {
  std::string folder;
  int source_id = 0;
  double diameter_m = 0.0;
  Eigen::Vector2d center;
};

std::vector<MergedCrater> ReadMerged(const fs::path& gpkg, std::string* crs_name = nullptr) {
  GDALAllRegister();
  GDALDatasetUniquePtr ds(GDALDataset::Open(gpkg.c_str(), GDAL_OF_VECTOR));
  EXPECT_TRUE(ds) << gpkg;
  if (!ds) return {};
  OGRLayer* layer = ds->GetLayerByName("craters");
  EXPECT_NE(layer, nullptr);
  if (crs_name != nullptr) *crs_name = layer->GetSpatialRef()->GetName();
  std::vector<MergedCrater> out;
  for (auto& f : *layer) {
    out.push_back({f->GetFieldAsString("source_folder"),
                   f->GetFieldAsInteger("source_id"),
                   f->GetFieldAsDouble("diameter_m"),
                   {f->GetFieldAsDouble("map_x"), f->GetFieldAsDouble("map_y")}});
  }
  return out;
}

// Random pairs of circles, a of 2-12 px at the origin and b offset by up to `max_offset` per axis
// with b / a diameters in [min_ratio, max_ratio): `same` must be symmetric, and every pair it
// joins must lie closer than `radius` of either diameter. Returns how many pairs it joined.
struct PairDraw {
  double max_offset, min_ratio, max_ratio;
  unsigned seed;
};
int PairsJoinedSymmetricallyWithinRadius(bool (*same)(const CraterCircle&, const CraterCircle&),
                                         double (*radius)(double), const PairDraw& draw) {
  std::mt19937 rng(draw.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int joined = 0;
  for (int i = 0; i < 20000; ++i) {
    const CraterCircle a{{0, 0}, 10.0 * (0.2 + u(rng))};
    const CraterCircle b{
        {draw.max_offset * u(rng), draw.max_offset * u(rng)},
        a.diameter * (draw.min_ratio + (draw.max_ratio - draw.min_ratio) * u(rng))};
    EXPECT_EQ(same(a, b), same(b, a));
    if (!same(a, b)) continue;
    ++joined;
    const double distance = (a.center - b.center).norm();
    EXPECT_LT(distance, radius(a.diameter));
    EXPECT_LT(distance, radius(b.diameter));
  }
  return joined;
}

TEST(SameCrater, EitherWayIsSymmetricAndLiesWithinTheSearchRadius) {
  // 14 / 10 = 1.4 is beyond 1.3, but 10 / 14 = 0.71 is within [0.7, 1.3].
  EXPECT_FALSE(SameCrater({{0, 0}, 10.0}, {{3.4, 0}, 14.0}));
  EXPECT_TRUE(SameCrater({{0, 0}, 14.0}, {{3.4, 0}, 10.0}));
  EXPECT_TRUE(SameCraterEitherWay({{0, 0}, 10.0}, {{3.4, 0}, 14.0}));
  EXPECT_FALSE(SameCraterEitherWay({{0, 0}, 10.0}, {{3.6, 0}, 14.0}));  // 3.6 > 14 / 4
  EXPECT_FALSE(SameCraterEitherWay({{0, 0}, 10.0}, {{0, 0}, 15.0}));    // 10 / 15 < 0.7
  EXPECT_FALSE(SameCraterEitherWay({{0, 0}, 0.0}, {{0, 0}, 0.0}));
  EXPECT_GT(PairsJoinedSymmetricallyWithinRadius(SameCraterEitherWay, SameCraterSearchRadius,
                                                 {5.0, 0.6, 1.5, 11}),
            1000);
}

TEST(SameCrater, OrConcentricIsSymmetricAndLiesWithinItsSearchRadius) {
  EXPECT_TRUE(SameCraterOrConcentric({{0, 0}, 20.0}, {{1, 1}, 14.0}));   // 1.43x, concentric
  EXPECT_FALSE(SameCraterOrConcentric({{0, 0}, 20.0}, {{0, 0}, 33.0}));  // 1.65x
  EXPECT_FALSE(SameCraterOrConcentric({{0, 0}, 30.0}, {{8, 0}, 30.0}));  // 8 > 15 / 2
  EXPECT_GT(PairsJoinedSymmetricallyWithinRadius(
                SameCraterOrConcentric, SameCraterOrConcentricSearchRadius, {6.0, 0.5, 1.8, 12}),
            1000);
}

TEST(CatalogueImageFolderName, NumbersTheImageAndKeepsASafeStem) {
  EXPECT_EQ(CatalogueImageFolderName(7, "/data/ctx/MC11E-G.png"), "007_MC11E-G");
  EXPECT_EQ(CatalogueImageFolderName(12, "dir/a tile (2).cub"), "012_a_tile__2_");
  EXPECT_EQ(CatalogueImageFolderName(1234, "x.tif"), "1234_x");
}

TEST(ReadCatalogueImageList, SkipsBlankLinesAndCommentsAndNamesTheLineOfAMissingFile) {
  const TempDir dir;
  std::ofstream(dir.path() / "a.tif") << "x";
  std::ofstream(dir.path() / "b.tif") << "x";
  const fs::path list = dir.path() / "list.txt";
  std::ofstream(list) << "# tiles\n\n  " << (dir.path() / "a.tif").string() << "  \r\n"
                      << (dir.path() / "b.tif").string() << "\n";
  const std::vector<fs::path> images = ReadCatalogueImageList(list);
  ASSERT_EQ(images.size(), 2u);
  EXPECT_EQ(images[0], dir.path() / "a.tif");
  EXPECT_EQ(images[1], dir.path() / "b.tif");
  std::ofstream(list, std::ios::app) << "# more\n" << (dir.path() / "c.tif").string() << "\n";
  EXPECT_EQ(ErrorMessageOf([&] { ReadCatalogueImageList(list); }),
            list.string() + " line 6: " + (dir.path() / "c.tif").string() + ": no such file");
}

TEST(RunCraterCatalogueImage, RecordsAnImageWithoutGroundPositionsOrUnreadableAsFailed) {
  const TempDir dir;
  GeoRaster plain;
  plain.bands = {cv::Mat(64, 64, CV_8U, cv::Scalar(100))};
  WriteGeoTiff(dir.path() / "plain.tif", plain);
  std::ofstream(dir.path() / "notes.tif") << "not a raster\n";
  const fs::path unit = dir.path() / "images" / "001_plain";
  // An earlier run's files in the folder go when the image fails now.
  fs::create_directories(unit);
  std::ofstream(unit / "craters.csv") << "id\n";
  const CatalogueImageRecord plain_record =
      RunCraterCatalogueImage(dir.path() / "plain.tif", unit, {});
  EXPECT_FALSE(plain_record.ok);
  EXPECT_NE(plain_record.error.find("plain.tif: a crater catalogue needs ground positions"),
            std::string::npos)
      << plain_record.error;
  EXPECT_NE(plain_record.error.find("give a georeferenced GeoTIFF or ISIS cube"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(unit / "craters.csv"));
  const CatalogueImageRecord read = ReadCatalogueImageRecord(unit);
  EXPECT_FALSE(read.ok);
  EXPECT_EQ(read.error, plain_record.error);

  const CatalogueImageRecord text =
      RunCraterCatalogueImage(dir.path() / "notes.tif", dir.path() / "images" / "002_notes", {});
  EXPECT_FALSE(text.ok);
  EXPECT_NE(text.error.find("notes.tif: not a readable raster"), std::string::npos) << text.error;
}

// The field scene (crater_scene.h) cut into two georeferenced images that overlap by 300 px:
// each image's unit, then the merge, finds the scene's craters once.
TEST(CraterCatalogue, TwoOverlappingImagesOfOneSceneGiveEachCraterOnce) {
  const TempDir dir;
  const testing::CraterScene scene = testing::MakeFieldScene(315.0);
  const GeoRaster& whole = scene.products.image;
  CraterImageOptions options;
  options.detector.method = CraterMethod::kEdges;
  options.sun_azimuth_deg = 315.0;
  options.min_diameter = 12.0;
  std::vector<fs::path> units;
  for (const int col0 : {0, 250}) {
    GeoRaster crop = whole;
    crop.bands = {whole.bands[0](cv::Rect(col0, 0, 550, whole.bands[0].rows)).clone()};
    crop.geotransform.c[0] += col0 * whole.geotransform.c[1];
    const fs::path image = dir.path() / ("crop" + std::to_string(col0) + ".tif");
    WriteGeoTiff(image, crop);
    units.push_back(dir.path() / "images" / CatalogueImageFolderName(1 + col0 / 250, image));
    const CatalogueImageRecord r = RunCraterCatalogueImage(image, units.back(), options);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_GT(r.craters, 5);
    for (const char* name : {"craters.csv", "craters.gpkg", "overlay.png", "summary.json"}) {
      EXPECT_TRUE(fs::exists(units.back() / name)) << name;
    }
  }
  const CatalogueMergeSummary s = MergeCraterCatalogues(units, dir.path());
  EXPECT_EQ(s.images_ok, 2);
  EXPECT_GT(s.duplicates_removed, 3);  // the overlap holds several of the scene's craters
  EXPECT_EQ(s.kept + s.duplicates_removed, s.detected);
  const std::vector<MergedCrater> merged = ReadMerged(dir.path() / "craters.gpkg");
  ASSERT_EQ(static_cast<int>(merged.size()), s.kept);
  for (size_t i = 0; i < merged.size(); ++i) {
    for (size_t j = i + 1; j < merged.size(); ++j) {
      EXPECT_FALSE(SameCraterEitherWay({merged[i].center, merged[i].diameter_m},
                                       {merged[j].center, merged[j].diameter_m}))
          << i << " " << j;
    }
  }
  // Each true crater found is found once.
  const double gsd = whole.geotransform.c[1];
  for (const Ellipse& t : scene.truth_px) {
    const Eigen::Vector2d c = whole.geotransform.PixelToMap(t.center.x(), t.center.y());
    int found = 0;
    for (const MergedCrater& m : merged) {
      found += SameCrater({c, (t.semi_major + t.semi_minor) * gsd}, {m.center, m.diameter_m});
    }
    EXPECT_LE(found, 1) << t.center.transpose();
  }
}

// Three craters seen by two images overlapping by 400 px: the complete rim beats a partial one,
// a fitted ellipse beats the network's circle, then the smaller relative centre sigma wins.
TEST(MergeCraterCatalogues, KeepsTheBetterFittedRimOfEachCraterInTheOverlap) {
  const TempDir dir;
  const std::string wkt = Crs::FromUserInput("IAU_2015:49910").Wkt();
  const GeoTransform gt_a = GeoTransform::NorthUp(0.0, 0.0, 6.0, 6.0);
  const GeoTransform gt_b = GeoTransform::NorthUp(3600.0, 0.0, 6.0, 6.0);  // A's column 600
  // In A: id 1-3 in the overlap, 4 outside it; in B (600 px to the left): id 1-3 the same
  // craters, 4 outside A, 5 a smaller crater nested in the third.
  const std::vector<CraterDetection> a = {
      Rim({700, 100}, 30, 0.3),                               // complete
      Rim({800, 300}, 40, 0.2, false, /*rim_fitted=*/false),  // the network's circle
      Rim({900, 500}, 50, 0.5),                               // larger relative sigma
      Rim({100, 100}, 20, 0.3)};
  const std::vector<CraterDetection> b = {Rim({100.8, 100.5}, 33, 0.1, /*partial=*/true),
                                          Rim({200.5, 300}, 38, 0.6), Rim({300, 500.7}, 52, 0.2),
                                          Rim({900, 900}, 25, 0.3), Rim({300, 500}, 20, 0.1)};
  const std::vector<fs::path> units = {
      WriteImageFolder(dir.path() / "images/001_a", "a.tif", a, gt_a, wkt),
      WriteImageFolder(dir.path() / "images/002_b", "b.tif", b, gt_b, wkt)};
  const CatalogueMergeSummary s = MergeCraterCatalogues(units, dir.path());
  EXPECT_EQ(s.detected, 9);
  EXPECT_EQ(s.kept, 6);
  EXPECT_EQ(s.duplicates_removed, 3);
  ASSERT_EQ(s.images.size(), 2u);
  EXPECT_EQ(s.images[0].kept, 2);  // 1 and 4
  EXPECT_EQ(s.images[1].kept, 4);  // 2, 3, 4 and 5
  std::string crs_name;
  const std::vector<MergedCrater> merged = ReadMerged(dir.path() / "craters.gpkg", &crs_name);
  EXPECT_EQ(crs_name, "Mars (2015) - Sphere / Ocentric / Equirectangular, clon = 0");
  std::vector<std::pair<std::string, int>> sources;
  for (const MergedCrater& m : merged) sources.emplace_back(m.folder, m.source_id);
  const std::vector<std::pair<std::string, int>> expected = {
      {"001_a", 1}, {"001_a", 4}, {"002_b", 2}, {"002_b", 3}, {"002_b", 4}, {"002_b", 5}};
  EXPECT_EQ(sources, expected);
  EXPECT_NEAR(merged[0].diameter_m, 180.0, 1e-9);
  const std::string table = ReadText(dir.path() / "images.csv");
  EXPECT_EQ(table,
            "folder,image,status,craters_detected,craters_kept,duplicates_removed,seconds,error\n"
            "001_a,a.tif,ok,4,2,2,0,\n"
            "002_b,b.tif,ok,5,4,1,0,\n");
  const std::string csv = ReadText(dir.path() / "craters.csv");
  EXPECT_EQ(csv.substr(0, csv.find(',', csv.find("diameter_m"))),
            "id,source_image,source_folder,source_id,diameter_m");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 7);
}

// An image in another CRS (true scale at 30 degrees, 9 m pixels) is compared in the first
// image's CRS: its craters are moved by PROJ, its metres scaled to the common CRS's.
TEST(MergeCraterCatalogues, ComparesImagesOfDifferentCrsAndPixelSize) {
  const TempDir dir;
  const Body sphere = Body::MarsSphere();
  const MapProjection first = MapProjection::Equirectangular(sphere, 0.0, 0.0);
  const MapProjection second = MapProjection::Equirectangular(sphere, RadFromDeg(30.0), 0.0);
  const GeoTransform gt_a = GeoTransform::NorthUp(0.0, 0.0, 6.0, 6.0);
  // Craters on the ground, in the first CRS [m]: centre and diameter.
  const std::vector<CraterCircle> ground = {{{2400.0, -600.0}, 150.0}, {{3000.0, -1800.0}, 300.0}};
  std::vector<CraterDetection> a, b;
  const Eigen::Vector2d b_origin = second.Forward(first.Inverse({1800.0, 0.0}));
  const GeoTransform gt_b = GeoTransform::NorthUp(b_origin.x(), b_origin.y(), 9.0, 9.0);
  for (const CraterCircle& g : ground) {
    a.push_back(Rim(gt_a.MapToPixel(g.center.x(), g.center.y()), g.diameter / 6.0, 0.3));
    const Eigen::Vector2d in_b = second.Forward(first.Inverse(g.center));
    // x lengths shrink by cos 30 in the second CRS; "a + b" of the ellipse there.
    CraterDetection d = Rim(gt_b.MapToPixel(in_b.x(), in_b.y()), 0.0, 0.1);
    d.ellipse.semi_major = 0.5 * g.diameter / 9.0;  // north-south
    d.ellipse.semi_minor = 0.5 * g.diameter * std::cos(RadFromDeg(30.0)) / 9.0;
    d.ellipse.angle = 0.5 * std::numbers::pi;
    b.push_back(d);
  }
  const std::vector<fs::path> units = {
      WriteImageFolder(dir.path() / "001_a", "a.tif", a, gt_a, first.Wkt()),
      WriteImageFolder(dir.path() / "002_b", "b.tif", b, gt_b, second.Wkt())};
  const CatalogueMergeSummary s = MergeCraterCatalogues(units, dir.path());
  EXPECT_EQ(s.detected, 4);
  EXPECT_EQ(s.kept, 2);  // the second image's, with the smaller sigma
  const std::vector<MergedCrater> merged = ReadMerged(dir.path() / "craters.gpkg");
  ASSERT_EQ(merged.size(), 2u);
  for (size_t i = 0; i < merged.size(); ++i) {
    EXPECT_EQ(merged[i].folder, "002_b");
    EXPECT_LT((merged[i].center - ground[i].center).norm(), 1e-3);
    // a + b with a in x scaled by 1/cos 30 and b unchanged: the area scale's root, 1.0746.
    const double expected = 0.5 * ground[i].diameter * (1.0 + std::cos(RadFromDeg(30.0))) /
                            std::sqrt(std::cos(RadFromDeg(30.0)));
    EXPECT_NEAR(merged[i].diameter_m, expected, 1e-6 * expected);
  }
  // A common CRS in degrees is refused.
  CatalogueMergeOptions geographic;
  geographic.crs = "IAU_2015:49900";
  EXPECT_NE(ErrorMessageOf([&] {
              MergeCraterCatalogues(units, dir.path(), geographic);
            }).find("is not a projected CRS in metres"),
            std::string::npos);
}

TEST(MergeCraterCatalogues, ListsFailedImagesAndWritesNoGeoPackageWithoutAnImageOk) {
  const TempDir dir;
  CatalogueImageRecord failed;
  failed.image = "dir, with comma/x.png";
  failed.error = "x.png: a crater catalogue needs ground positions, \"quoted\"";
  fs::create_directories(dir.path() / "001_x");
  WriteCatalogueImageRecord(dir.path() / "001_x", failed);
  const CatalogueMergeSummary s = MergeCraterCatalogues({dir.path() / "001_x"}, dir.path());
  EXPECT_EQ(s.images_failed, 1);
  EXPECT_EQ(s.kept, 0);
  EXPECT_FALSE(fs::exists(dir.path() / "craters.gpkg"));
  EXPECT_EQ(ReadText(dir.path() / "craters.csv"),
            "id,source_image,source_folder,source_id,diameter_m\n");
  EXPECT_EQ(ReadText(dir.path() / "images.csv"),
            "folder,image,status,craters_detected,craters_kept,duplicates_removed,seconds,error\n"
            "001_x,\"dir, with comma/x.png\",failed,0,0,0,0,\"x.png: a crater catalogue needs "
            "ground positions, \"\"quoted\"\"\"\n");
  // A folder the image never ran into.
  fs::create_directories(dir.path() / "002_y");
  EXPECT_EQ(ErrorMessageOf([&] { MergeCraterCatalogues({dir.path() / "002_y"}, dir.path()); }),
            (dir.path() / "002_y" / "image.json").string() +
                ": cannot open (the image was not run into this folder)");
}

}  // namespace
}  // namespace areomap
