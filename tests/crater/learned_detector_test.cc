#include "areomap/crater/learned_detector.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <utility>

#include <gdal.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_raster.h"
#include "areomap/crater/crater_score.h"
#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "crater_scene.h"
#include "small_tiled_raster.h"
#include "test_support.h"

namespace areomap {
namespace {

using testing::CraterScene;

const CraterScene& FieldScene() {
  static const CraterScene scene = testing::MakeFieldScene(120.0);
  return scene;
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

std::filesystem::path TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("areomap_learned_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(CraterNetwork, BuiltInModelGivesFourMapsAtHalfResolution) {
  CraterNetwork network;
  EXPECT_EQ(network.source(), "built-in");
  const CraterNetwork::Output out = network.Forward(cv::Mat::zeros(24, 40, CV_32F));
  for (const cv::Mat* m : {&out.heat, &out.dx, &out.dy, &out.log_diameter}) {
    EXPECT_EQ(m->rows, 12);
    EXPECT_EQ(m->cols, 20);
    EXPECT_EQ(m->type(), CV_32F);
  }
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(out.heat, &lo, &hi);
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 1.0);
}

TEST(CraterNetwork, MissingOrCorruptModelFileIsAnErrorNamingIt) {
  const auto dir = TempDir("model");
  const std::string missing = (dir / "missing.onnx").string();
  EXPECT_NE(
      ErrorOf([&] { CraterNetwork{missing}; }).find(missing + ": crater model file not found"),
      std::string::npos);
  const std::string corrupt = (dir / "corrupt.onnx").string();
  std::ofstream(corrupt) << "not a network at all";
  const std::string message = ErrorOf([&] { CraterNetwork{corrupt}; });
  EXPECT_NE(message.find(corrupt), std::string::npos) << message;
  // The command-line route: the option names the file before any work.
  CraterDetectorOptions options;
  options.learned.model_path = corrupt;
  EXPECT_NE(ErrorOf([&] {
              DetectCratersLearned(cv::Mat::zeros(64, 64, CV_32F), options, options.learned);
            }).find(corrupt),
            std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(LearnedDetectorOptions, CheckNamesTheField) {
  LearnedDetectorOptions o;
  o.min_score = 1.0;
  EXPECT_NE(ErrorOf([&] { o.Check(); }).find("LearnedDetectorOptions.min_score"),
            std::string::npos);
  o = {};
  o.edge_support_score = -0.1;
  EXPECT_NE(ErrorOf([&] { o.Check(); }).find("LearnedDetectorOptions.edge_support_score"),
            std::string::npos);
  o.edge_support_score = 0.0;  // keeps every edge rim
  EXPECT_NO_THROW(o.Check());
  o = {};
  o.tile_size = 16;
  EXPECT_NE(ErrorOf([&] { o.Check(); }).find("LearnedDetectorOptions.tile_size"),
            std::string::npos);
  EXPECT_EQ(CraterMethodFromString("edges"), CraterMethod::kEdges);
  EXPECT_EQ(ToString(CraterMethodFromString("learned")), "learned");
  EXPECT_NE(ErrorOf([] { CraterMethodFromString("hough"); }).find("'hough'"), std::string::npos);
}

// Any gain and bit depth give the same input (the std floor, 1e-3 of the local mean, scales
// with the gain too).
TEST(NormalizeForCraterNetwork, IsTheSameForAnyGainAndBitDepth) {
  cv::Mat byte;
  FieldScene().products.image.bands[0].convertTo(byte, CV_8U, 1.0 / 4.0);
  cv::Mat word, real;
  byte.convertTo(word, CV_16U, 64.0);
  byte.convertTo(real, CV_32F, 1.0 / 255.0);
  const cv::Mat a = NormalizeForCraterNetwork(byte);
  EXPECT_LT(cv::norm(a, NormalizeForCraterNetwork(word), cv::NORM_INF), 1e-3);
  EXPECT_LT(cv::norm(a, NormalizeForCraterNetwork(real), cv::NORM_INF), 1e-3);
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(a, &lo, &hi);
  EXPECT_GE(lo, -4.0);
  EXPECT_LE(hi, 4.0);
}

TEST(DetectCratersLearned, ConstantTinyAndAllNodataImagesGiveNoCraters) {
  const CraterDetectorOptions options;
  EXPECT_TRUE(DetectCratersLearned(cv::Mat(300, 200, CV_32F, cv::Scalar(7.0)), options).empty());
  EXPECT_TRUE(DetectCratersLearned(cv::Mat(1, 1, CV_8U, cv::Scalar(9)), options).empty());
  EXPECT_TRUE(DetectCratersLearned(cv::Mat(3, 5, CV_16U, cv::Scalar(9)), options).empty());
  const cv::Mat nodata(128, 128, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_TRUE(DetectCratersLearned(nodata, options).empty());
}

// How far nodata reaches into the finds of a crater of `diameter` px: its radius plus the reach
// of the pyramid level that finds it (the network's ~37 px and the normalisation's 15 px half
// box, times 2^level; level l >= 1 finds 24 2^(l-1) to 24 2^l px).
double NodataReachPx(double diameter) {
  const int level =
      diameter < 24.0 ? 0 : 1 + static_cast<int>(std::floor(std::log2(diameter / 24.0)));
  return 0.5 * diameter + 52.0 * std::pow(2.0, level);
}

// Of the craters of `full` that `clear` accepts, how many `found` holds again (centre within a
// tenth of the diameter): {clear, found again}.
std::pair<int, int> FoundAgain(const std::vector<CraterDetection>& full,
                               const std::vector<CraterDetection>& found,
                               const std::function<bool(const CraterDetection&)>& clear) {
  int clear_count = 0, again = 0;
  for (const CraterDetection& f : full) {
    if (!clear(f)) continue;
    ++clear_count;
    for (const CraterDetection& d : found) {
      if ((d.ellipse.center - f.ellipse.center).norm() < 0.1 * f.Diameter()) {
        ++again;
        break;
      }
    }
  }
  return {clear_count, again};
}

TEST(DetectCratersLearned, FindsNoCraterInNodataAndTheSameOnesBesideIt) {
  cv::Mat image;
  FieldScene().products.image.bands[0].convertTo(image, CV_32F);
  const std::vector<CraterDetection> full = DetectCratersLearned(image, {});
  cv::Mat holed = image.clone();
  const int half = image.cols / 2;
  holed.colRange(half, image.cols).setTo(std::numeric_limits<float>::quiet_NaN());
  const std::vector<CraterDetection> found = DetectCratersLearned(holed, {});
  ASSERT_FALSE(found.empty());
  for (const CraterDetection& d : found) {
    EXPECT_LT(d.ellipse.center.x(), half) << "a crater centred in the nodata half";
  }
  // Craters well inside the valid half are found as before.
  const auto [far_left, kept_left] = FoundAgain(full, found, [&](const CraterDetection& f) {
    return f.ellipse.center.x() + NodataReachPx(f.Diameter()) <= half;
  });
  ASSERT_GT(far_left, 3);
  EXPECT_GE(kept_left, far_left - 1);
}

// Nodata stripes across the real HRSC image: the craters between them are found as without them,
// also right of the first stripe. (A NaN that reached the normalisation's box filter once
// blanked the rest of its row: 12 of 165 craters were left, all left of the first stripe.)
TEST(DetectCratersLearned, FindsTheCratersBetweenNodataStripesOfARealImage) {
  cv::Mat image;
  ReadImage(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png")
      .convertTo(image, CV_32F);
  CraterDetectorOptions options;
  options.learned.refine_rims = false;
  const std::vector<CraterDetection> full = DetectCratersLearned(image, options);
  constexpr int kFirst = 150, kPeriod = 300, kWidth = 30;
  cv::Mat striped = image.clone();
  for (int x0 = kFirst; x0 < image.cols; x0 += kPeriod) {
    striped.colRange(x0, std::min(x0 + kWidth, image.cols))
        .setTo(std::numeric_limits<float>::quiet_NaN());
  }
  const std::vector<CraterDetection> found = DetectCratersLearned(striped, options);
  const auto distance_to_stripes = [&](double x) {
    const double into_period = std::fmod(x - kFirst + kPeriod, static_cast<double>(kPeriod));
    return into_period < kWidth ? 0.0 : std::min(into_period - kWidth, kPeriod - into_period);
  };
  for (const CraterDetection& d : found) {
    EXPECT_GT(distance_to_stripes(d.ellipse.center.x()), 0.0) << "a crater centred in nodata";
  }
  const auto [clear, again] = FoundAgain(full, found, [&](const CraterDetection& f) {
    return f.ellipse.center.x() > kFirst + kWidth &&
           distance_to_stripes(f.ellipse.center.x()) > NodataReachPx(f.Diameter());
  });
  ASSERT_GE(clear, 20);
  EXPECT_GE(again, 0.9 * clear) << clear << " craters clear of the stripes, " << again
                                << " found again";
}

TEST(DetectCratersLearned, SameCratersFrom8BitAnd16BitAndFloatImages) {
  cv::Mat byte;
  FieldScene().products.image.bands[0].convertTo(byte, CV_8U, 1.0 / 4.0);
  cv::Mat word, real;
  byte.convertTo(word, CV_16U, 64.0, 1000.0);  // an offset too, as a 16-bit product may have
  byte.convertTo(real, CV_32F, 1.0 / 255.0);
  CraterDetectorOptions options;
  options.learned.refine_rims = false;
  const std::vector<CraterDetection> a = DetectCratersLearned(byte, options);
  const std::vector<CraterDetection> b = DetectCratersLearned(word, options);
  const std::vector<CraterDetection> c = DetectCratersLearned(real, options);
  ASSERT_GE(a.size(), 10u);
  for (const auto* other : {&b, &c}) {
    const CraterScore s = ScoreCraters(CirclesOf(a), CirclesOf(*other), {0.0, 1e9});
    EXPECT_GE(s.all.recall, 0.95);
    EXPECT_GE(s.all.precision, 0.95);
  }
}

// Pyramid levels run in tiles with a margin wider than the network's reach: a raster read in
// 64 px tiles gives the craters of one whole-image pass.
TEST(DetectCratersLearned, TiledRasterGivesTheCratersOfTheWholeImage) {
  const auto dir = TempDir("tiles");
  cv::Mat image;
  FieldScene().products.image.bands[0].convertTo(image, CV_32F);
  GeoRaster raster;
  raster.bands = {image};
  WriteGeoTiff(dir / "scene.tif", raster);
  const RasterDataset dataset = RasterDataset::Open(dir / "scene.tif");
  CraterDetectorOptions options;
  options.learned.refine_rims = false;
  options.learned.tile_size = 64;
  int calls = 0;
  const std::vector<CraterDetection> tiled =
      DetectCratersLearned(dataset, options, options.learned, [&](double, std::string_view) {
        ++calls;
        return true;
      });
  EXPECT_GT(calls, 100);
  options.learned.tile_size = 4096;
  const std::vector<CraterDetection> whole = DetectCratersLearned(image, options, options.learned);
  ASSERT_EQ(tiled.size(), whole.size());
  ASSERT_FALSE(whole.empty());
  for (size_t i = 0; i < whole.size(); ++i) {
    EXPECT_LT((tiled[i].ellipse.center - whole[i].ellipse.center).norm(), 1e-3) << i;
    EXPECT_NEAR(tiled[i].Diameter(), whole[i].Diameter(), 1e-3) << i;
  }
  // DetectCratersInRaster takes the learned path for images when asked.
  options.method = CraterMethod::kLearned;
  options.learned.tile_size = 1024;
  options.learned.refine_rims = true;
  EXPECT_EQ(DetectCratersInRaster(dataset, RimSource::kImage, options).size(),
            DetectCratersLearned(image, options).size());
  std::filesystem::remove_all(dir);
}

// The rim fits read the raster from several threads at once: each must read through its own
// GDAL handle (one shared handle decoded compressed tiles wrongly and failed the read of a
// 10 000 px raster, larger than GDAL's block cache). A mosaic of the field scene in small deflate
// tiles, many craters, a 1 MB block cache so that the fits decode: the same craters as the image
// in memory, every time.
TEST(DetectCratersLearned, RimFitsReadACompressedRasterFromManyThreads) {
  const auto dir = TempDir("threads");
  cv::Mat scene, image;
  FieldScene().products.image.bands[0].convertTo(scene, CV_32F);
  cv::repeat(scene, 3, 3, image);
  const RasterDataset dataset = testing::WriteSmallTiledRaster(dir / "mosaic.tif", image);
  CraterDetectorOptions options;
  options.method = CraterMethod::kLearned;
  const std::vector<CraterDetection> in_memory = DetectCratersLearned(image, options);
  ASSERT_GT(in_memory.size(), 150u);
  const GIntBig cache_bytes = GDALGetCacheMax64();
  GDALSetCacheMax64(1 << 20);
  for (int run = 0; run < 2; ++run) {
    std::vector<CraterDetection> read;
    EXPECT_NO_THROW(read = DetectCratersInRaster(dataset, RimSource::kImage, options));
    EXPECT_EQ(read.size(), in_memory.size()) << run;
    for (size_t i = 0; i < std::min(read.size(), in_memory.size()); ++i) {
      EXPECT_LT((read[i].ellipse.center - in_memory[i].ellipse.center).norm(), 1e-3) << i;
    }
  }
  GDALSetCacheMax64(cache_bytes);
  std::filesystem::remove_all(dir);
}

TEST(DetectCratersLearned, CancellingStopsWithAnError) {
  cv::Mat image;
  FieldScene().products.image.bands[0].convertTo(image, CV_32F);
  CraterDetectorOptions options;
  options.learned.tile_size = 128;
  int calls = 0;
  const std::string message = ErrorOf([&] {
    DetectCratersLearned(image, options, options.learned,
                         [&](double, std::string_view) { return ++calls < 3; });
  });
  EXPECT_NE(message.find("cancelled"), std::string::npos);
}

// Generated scene (HiRISE-like 0.5 m/px, craters 10-160 px; the network was trained on other
// generated scenes, eval/crater_training_scenes.cc): measured R 1.000 (23 of 23), P 0.920 (its two
// false finds lie inside the 122 px crater, which the default combined method drops as the rim's
// floor), median centre error 0.12 px where the rim was fitted. Regression guards; the edge
// detector's precision is not reached (docs/crater-model.md).
TEST(DetectCratersLearned, FindsGeneratedCratersWithSubPixelAccuracy) {
  const CraterScene& scene = FieldScene();
  const std::vector<CraterDetection> found =
      DetectCratersLearned(scene.products.image.bands[0], {});
  const CraterScore score = ScoreCraters(CirclesOf(scene.truth_px), CirclesOf(found), {10.0, 1e9});
  std::vector<double> center_errors;
  int fitted = 0;
  for (const auto& [t, d] : score.matches) {
    const CraterDetection& det = found[static_cast<size_t>(d)];
    if (!det.rim_fitted) continue;
    ++fitted;
    center_errors.push_back(
        (det.ellipse.center - scene.truth_px[static_cast<size_t>(t)].center).norm());
  }
  RecordProperty("recall", std::to_string(score.all.recall));
  RecordProperty("precision", std::to_string(score.all.precision));
  RecordProperty("rims_fitted", fitted);
  RecordProperty("median_center_error_px", std::to_string(Median(center_errors)));
  EXPECT_GE(score.all.recall, 0.95);
  EXPECT_GE(score.all.precision, 0.9);
  EXPECT_GE(fitted, static_cast<int>(score.matches.size()) * 3 / 4);
  EXPECT_LT(Median(center_errors), 0.5);
}

// The C++ port against the training code: scripts/crater_model/make_reference.py ran the
// built-in model in PyTorch on a 256 x 256 crop of the HRSC image and wrote the network's
// circles of 4 px and more.
TEST(DetectCratersLearned, MatchesThePyTorchReferenceOnARealImage) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto reference = std::filesystem::path(AREOMAP_TEST_DATA_DIR) / "crater_net_reference.csv";
  const int x0 = 700, y0 = 300, size = 256;  // make_reference.py's crop
  const cv::Mat image = ReadImage(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png");
  const cv::Mat crop = image(cv::Rect(x0, y0, size, size)).clone();
  const std::vector<CraterCircle> expected = ReadCraterCsv(reference);
  CraterDetectorOptions options;
  options.min_diameter_px = 4.0;
  options.learned.refine_rims = false;
  const std::vector<CraterDetection> found = DetectCratersLearned(crop, options, options.learned);
  ASSERT_GE(expected.size(), 10u);
  ASSERT_EQ(found.size(), expected.size());
  const std::vector<CraterCircle> got = CirclesOf(found);
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_LT((got[i].center - expected[i].center).norm(), 0.01) << i;
    EXPECT_NEAR(got[i].diameter, expected[i].diameter, 0.01) << i;
  }
}

// Fitted rims meet the diameter limits; the network's circles meet them within 2 sigma of their
// diameter (0.108 D), since the network puts a crater at the limit under it as often as not.
// The real image gives circles (few rims show edges there), the generated scene fitted rims.
TEST(DetectCratersLearned, CirclesMeetTheDiameterLimitsWithinTheirUncertainty) {
  SKIP_WITHOUT_SHARED_DATA();
  CraterDetectorOptions options;
  options.min_diameter_px = 12.0;
  options.max_diameter_px = 40.0;
  const double tolerance = 2.0 * 0.108;
  int circles_beyond = 0, fitted = 0;
  const auto check = [&](const std::vector<CraterDetection>& found) {
    for (const CraterDetection& d : found) {
      if (d.rim_fitted) {
        ++fitted;
        EXPECT_GE(d.Diameter(), 12.0);
        EXPECT_LE(d.Diameter(), 40.0);
        continue;
      }
      EXPECT_GE(d.Diameter(), 12.0 / (1.0 + tolerance) - 1e-9);
      EXPECT_LE(d.Diameter(), 40.0 / (1.0 - tolerance) + 1e-9);
      if (d.Diameter() < 12.0 || d.Diameter() > 40.0) ++circles_beyond;
    }
  };
  check(DetectCratersLearned(
      ReadImage(testing::SharedDataDir() / "craters" / "hrsc_nanedi_north.png"), options));
  check(DetectCratersLearned(FieldScene().products.image.bands[0], options));
  EXPECT_GT(fitted, 0);
  EXPECT_GT(circles_beyond, 0);
}

// A crisp 19 px bowl on hrsc-bandeira tile3_24 that level 0 measures at 24.1 px (over its band)
// and level 1 at 22.3 px (under its own): each level above 0 also reports craters a little under
// its band, so it is found.
TEST(DetectCratersLearned, FindsACraterBetweenTwoPyramidBands) {
  SKIP_WITHOUT_SHARED_DATA();
  const cv::Mat tile =
      ReadImage(testing::SharedDataDir() / "craters-train" / "hrsc-bandeira" / "tile3_24.png");
  const CraterCircle bowl{{464.39, 248.97}, 18.9};  // the label
  const std::vector<CraterDetection> found = DetectCratersLearned(tile, {});
  const CraterScore score = ScoreCraters({bowl}, CirclesOf(found), {8.0, 1e9});
  EXPECT_EQ(score.all.matched_truth, 1);
}

// Real HRSC image (never trained on), craters >= 8 px, default learned options: measured F1 0.580
// (P 0.722, R 0.485). A regression guard: the target of 0.80 is not reached (docs/crater-model.md).
TEST(DetectCratersLearned, HrscNanediLabelledCraters) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto dir = testing::SharedDataDir() / "craters";
  const cv::Mat image = ReadImage(dir / "hrsc_nanedi_north.png");
  const std::vector<CraterCircle> truth = ReadCraterCsv(dir / "hrsc_nanedi_north_craters.csv");
  const std::vector<CraterDetection> found = DetectCratersLearned(image, {});
  const CraterScore score = ScoreCraters(truth, CirclesOf(found), {8.0, 16.0, 32.0, 1e9});
  RecordProperty("f1_ge_8px", std::to_string(score.all.f1));
  RecordProperty("precision", std::to_string(score.all.precision));
  RecordProperty("recall", std::to_string(score.all.recall));
  EXPECT_GE(score.all.f1, 0.55);
}

}  // namespace
}  // namespace areomap
