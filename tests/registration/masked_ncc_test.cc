#include "areomap/registration/masked_ncc.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include "test_support.h"

#include "areomap/map/error.h"

namespace areomap {
namespace {

// The options with the FFT route forced (the cost model would pick direct summation for the
// small problems these tests compare against it).
MaskedNccOptions Fft(MaskedNccOptions options) {
  options.method = NccMethod::kFft;
  return options;
}

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Uniform noise blurred with a Gaussian of `sigma` [px] (no blur for sigma = 0), scaled to
// roughly unit standard deviation.
cv::Mat RandomTexture(int rows, int cols, double sigma, cv::RNG& rng) {
  cv::Mat noise(rows, cols, CV_32F);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
  if (sigma > 0.0) cv::GaussianBlur(noise, noise, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  cv::Scalar mean, stddev;
  cv::meanStdDev(noise, mean, stddev);
  noise = (noise - mean[0]) / stddev[0];
  return noise;
}

// A mask with about `valid_fraction` of the pixels valid (nonzero).
cv::Mat RandomMask(int rows, int cols, double valid_fraction, cv::RNG& rng) {
  cv::Mat mask(rows, cols, CV_8U);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c)
      mask.at<std::uint8_t>(r, c) = rng.uniform(0.0, 1.0) < valid_fraction;
  }
  return mask;
}

// Puts NaN in about `fraction` of the pixels (they must then count as invalid).
void AddNaNHoles(cv::Mat& image, double fraction, cv::RNG& rng) {
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      if (rng.uniform(0.0, 1.0) < fraction) image.at<float>(r, c) = kNaNf;
    }
  }
}

// Expects equal overlaps, NaN at the same shifts and scores within `tolerance`; returns the
// number of finite scores compared.
int ExpectSurfacesEqual(const MaskedNccSurface& fft, const MaskedNccSurface& naive,
                        double tolerance, double min_finite_fraction = 0.25) {
  EXPECT_EQ(fft.shift_x0, naive.shift_x0);
  EXPECT_EQ(fft.shift_y0, naive.shift_y0);
  if (fft.ncc.size() != naive.ncc.size()) {
    ADD_FAILURE() << "surface sizes differ: " << fft.ncc.size() << " vs " << naive.ncc.size();
    return 0;
  }
  int finite = 0;
  int mismatches = 0;
  double max_error = 0.0;
  for (int r = 0; r < fft.ncc.rows; ++r) {
    for (int c = 0; c < fft.ncc.cols; ++c) {
      const float a = fft.ncc.at<float>(r, c);
      const float b = naive.ncc.at<float>(r, c);
      if (fft.overlap.at<std::int32_t>(r, c) != naive.overlap.at<std::int32_t>(r, c) ||
          std::isnan(a) != std::isnan(b)) {
        if (++mismatches <= 5) {
          ADD_FAILURE() << "at (" << r << ", " << c << "): overlap "
                        << fft.overlap.at<std::int32_t>(r, c) << " vs "
                        << naive.overlap.at<std::int32_t>(r, c) << ", NCC " << a << " vs " << b;
        }
        continue;
      }
      if (std::isnan(a)) continue;
      ++finite;
      max_error = std::max(max_error, static_cast<double>(std::abs(a - b)));
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_LE(max_error, tolerance);
  EXPECT_GE(finite, min_finite_fraction * static_cast<double>(fft.ncc.total()))
      << "too few defined shifts to compare";
  return finite;
}

TEST(MaskedNcc, FftMatchesNaiveSummationOnRandomMaskedImagesWithNaNHoles) {
  cv::RNG rng(20240611);
  struct Case {
    int fixed_rows, fixed_cols, moving_rows, moving_cols;
  };
  const Case cases[] = {
      {32, 32, 8, 8}, {41, 37, 11, 9}, {33, 50, 16, 7}, {25, 19, 25, 19}, {20, 31, 24, 9}};
  MaskedNccOptions options;
  options.min_overlap_pixels = 3;
  options.min_overlap_fraction = 0.0;
  for (const Case& k : cases) {
    SCOPED_TRACE(::testing::Message() << "fixed " << k.fixed_rows << "x" << k.fixed_cols
                                      << ", moving " << k.moving_rows << "x" << k.moving_cols);
    cv::Mat fixed = RandomTexture(k.fixed_rows, k.fixed_cols, 0.0, rng) * 40.0 + 500.0;
    cv::Mat moving = RandomTexture(k.moving_rows, k.moving_cols, 0.0, rng) * 3.0 - 7.0;
    AddNaNHoles(fixed, 0.05, rng);
    AddNaNHoles(moving, 0.05, rng);
    const cv::Mat fixed_mask = RandomMask(k.fixed_rows, k.fixed_cols, 0.8, rng);
    const cv::Mat moving_mask = RandomMask(k.moving_rows, k.moving_cols, 0.8, rng);
    const MaskedNccSurface fft = MaskedNcc(fixed, fixed_mask, moving, moving_mask, Fft(options));
    const MaskedNccSurface naive = MaskedNccNaive(fixed, fixed_mask, moving, moving_mask, options);
    EXPECT_EQ(fft.shift_x0, -(k.moving_cols - 1));
    EXPECT_EQ(fft.shift_y0, -(k.moving_rows - 1));
    EXPECT_EQ(fft.ncc.rows, k.fixed_rows + k.moving_rows - 1);
    EXPECT_EQ(fft.ncc.cols, k.fixed_cols + k.moving_cols - 1);
    ExpectSurfacesEqual(fft, naive, 1e-4);
    // A fixed image without holes takes a shortcut (integral images for three sums).
    const cv::Mat whole = RandomTexture(k.fixed_rows, k.fixed_cols, 0.0, rng);
    ExpectSurfacesEqual(MaskedNcc(whole, {}, moving, moving_mask, Fft(options)),
                        MaskedNccNaive(whole, {}, moving, moving_mask, options), 1e-4);
  }
}

TEST(MaskedNcc, SearchWindowSurfaceMatchesNaiveAndTheFullSurface) {
  cv::RNG rng(7);
  cv::Mat fixed = RandomTexture(60, 70, 1.0, rng);
  const cv::Mat moving = RandomTexture(13, 17, 1.0, rng);
  const cv::Mat moving_mask = RandomMask(13, 17, 0.7, rng);
  AddNaNHoles(fixed, 0.1, rng);
  MaskedNccOptions options;
  options.min_overlap_fraction = 0.2;
  // Clipped to the shifts where the template touches the image: x >= -16, y <= 59.
  options.search_window = ShiftWindow{-25, 9, 40, 70};
  const MaskedNccSurface window = MaskedNcc(fixed, {}, moving, moving_mask, Fft(options));
  EXPECT_EQ(window.shift_x0, -16);
  EXPECT_EQ(window.shift_y0, 40);
  EXPECT_EQ(window.ncc.cols, 9 - (-16) + 1);
  EXPECT_EQ(window.ncc.rows, 59 - 40 + 1);
  ExpectSurfacesEqual(window, MaskedNccNaive(fixed, {}, moving, moving_mask, options), 1e-4);

  options.search_window.reset();
  const MaskedNccSurface full = MaskedNcc(fixed, {}, moving, moving_mask, options);
  MaskedNccSurface cut;
  const cv::Rect roi(window.shift_x0 - full.shift_x0, window.shift_y0 - full.shift_y0,
                     window.ncc.cols, window.ncc.rows);
  cut.ncc = full.ncc(roi);
  cut.overlap = full.overlap(roi);
  cut.shift_x0 = window.shift_x0;
  cut.shift_y0 = window.shift_y0;
  ExpectSurfacesEqual(window, cut, 1e-4);
}

TEST(MaskedNcc, FftMatchesNaiveSummationInRandomSearchWindows) {
  cv::RNG rng(11);
  cv::Mat fixed = RandomTexture(45, 52, 1.0, rng);
  const cv::Mat moving = RandomTexture(12, 9, 0.5, rng);
  AddNaNHoles(fixed, 0.05, rng);
  const cv::Mat fixed_mask = RandomMask(45, 52, 0.9, rng);
  const cv::Mat moving_mask = RandomMask(12, 9, 0.8, rng);
  const cv::Mat whole = RandomTexture(45, 52, 1.0, rng);  // No holes: the shortcut path.
  MaskedNccOptions options;
  options.min_overlap_fraction = 0.1;
  // Template wholly inside the image (the padding is then just the image size), a single
  // shift, and random windows that may run over any edge.
  std::vector<ShiftWindow> windows = {{0, 52 - 9, 0, 45 - 12}, {7, 7, 30, 30}};
  for (int k = 0; k < 10; ++k) {
    const int x = rng.uniform(-20, 60);
    const int y = rng.uniform(-20, 50);
    windows.push_back({x, x + rng.uniform(0, 25), y, y + rng.uniform(0, 25)});
  }
  int windows_with_scores = 0;
  for (const ShiftWindow& w : windows) {
    SCOPED_TRACE(::testing::Message() << "window x " << w.min_shift_x << ".." << w.max_shift_x
                                      << ", y " << w.min_shift_y << ".." << w.max_shift_y);
    options.search_window = w;
    const MaskedNccSurface fft = MaskedNcc(fixed, fixed_mask, moving, moving_mask, Fft(options));
    const MaskedNccSurface naive = MaskedNccNaive(fixed, fixed_mask, moving, moving_mask, options);
    ASSERT_EQ(fft.empty(), naive.empty());
    if (fft.empty()) continue;
    windows_with_scores += ExpectSurfacesEqual(fft, naive, 1e-4, /*min_finite_fraction=*/0.0) > 0;
    ExpectSurfacesEqual(MaskedNcc(whole, {}, moving, moving_mask, Fft(options)),
                        MaskedNccNaive(whole, {}, moving, moving_mask, options), 1e-4, 0.0);
  }
  EXPECT_GE(windows_with_scores, 8);
}

// A 256 x 256 random texture and a 48 x 48 template cut from it at (131, 77), with a little
// noise added and 30% of the template masked out (a blob) and filled with garbage, plus a
// hole of NaN in the fixed image under part of the template.
struct MaskedScene {
  cv::Mat fixed;
  cv::Mat moving;
  cv::Mat moving_mask;
  static constexpr int kShiftX = 131;
  static constexpr int kShiftY = 77;
};

MaskedScene MakeMaskedScene() {
  cv::RNG rng(42);
  MaskedScene scene;
  scene.fixed = RandomTexture(256, 256, 1.5, rng);
  scene.moving = scene.fixed(cv::Rect(MaskedScene::kShiftX, MaskedScene::kShiftY, 48, 48)).clone();
  cv::Mat noise(48, 48, CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 0.1);
  scene.moving += noise;
  // Mask out the 30% of pixels where a smooth random field is lowest: blobs, like occlusions.
  const cv::Mat field = RandomTexture(48, 48, 4.0, rng);
  cv::Mat sorted = field.reshape(1, 1).clone();
  cv::sort(sorted, sorted, cv::SORT_ASCENDING);
  const float threshold = sorted.at<float>(0, static_cast<int>(0.3 * sorted.cols));
  scene.moving_mask = field >= threshold;
  scene.moving.setTo(1000.0f, ~scene.moving_mask);
  scene.fixed(cv::Rect(100, 70, 40, 20)).setTo(kNaNf);
  return scene;
}

TEST(MaskedNcc, RecoversIntegerShiftWithThirtyPercentOfTemplateMaskedOut) {
  const MaskedScene scene = MakeMaskedScene();
  const double masked = 1.0 - cv::countNonZero(scene.moving_mask) / (48.0 * 48.0);
  ASSERT_NEAR(masked, 0.3, 0.01);
  const MaskedNccSurface surface = MaskedNcc(scene.fixed, {}, scene.moving, scene.moving_mask);
  const NccPeak peak = FindPeak(surface);
  EXPECT_TRUE(peak.found);
  EXPECT_TRUE(peak.confident) << peak.BriefReport();
  EXPECT_EQ(peak.shift_x, MaskedScene::kShiftX);
  EXPECT_EQ(peak.shift_y, MaskedScene::kShiftY);
  EXPECT_NEAR(peak.subpixel_x, MaskedScene::kShiftX, 0.1);
  EXPECT_NEAR(peak.subpixel_y, MaskedScene::kShiftY, 0.1);
  EXPECT_GT(peak.value, 0.95);
  EXPECT_GT(peak.peak_ratio, 2.0);
  EXPECT_GT(peak.sharpness, 0.0);
  EXPECT_TRUE(peak.reason.empty());
}

TEST(MaskedNcc, RecoversSubpixelShiftOfSmoothTexture) {
  cv::RNG rng(3);
  const cv::Mat image = RandomTexture(160, 160, 4.0, rng);
  const double true_x = 60.0 + 0.3;
  const double true_y = 50.0 - 0.4;
  // template(i, j) = image(i + true_y, j + true_x).
  const cv::Mat to_image = (cv::Mat_<double>(2, 3) << 1.0, 0.0, true_x, 0.0, 1.0, true_y);
  cv::Mat moving;
  cv::warpAffine(image, moving, to_image, cv::Size(40, 40), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP);
  const MaskedNccSurface surface = MaskedNcc(image, {}, moving, {});
  for (const SubpixelFit fit : {SubpixelFit::kQuadratic2d, SubpixelFit::kSeparableParabola}) {
    PeakOptions options;
    options.subpixel_fit = fit;
    const NccPeak peak = FindPeak(surface, options);
    EXPECT_TRUE(peak.confident) << peak.BriefReport();
    EXPECT_TRUE(peak.subpixel_refined);
    EXPECT_NEAR(peak.subpixel_x, true_x, 0.1) << peak.BriefReport();
    EXPECT_NEAR(peak.subpixel_y, true_y, 0.1) << peak.BriefReport();
  }
}

TEST(MaskedNcc, UnrelatedNoiseTemplateIsNotConfident) {
  cv::RNG rng(99);
  const cv::Mat fixed = RandomTexture(256, 256, 1.5, rng);
  const cv::Mat moving = RandomTexture(32, 32, 0.0, rng);
  const NccPeak peak = FindPeak(MaskedNcc(fixed, {}, moving, RandomMask(32, 32, 0.7, rng)));
  EXPECT_TRUE(peak.found);
  EXPECT_FALSE(peak.confident) << peak.BriefReport();
  EXPECT_FALSE(peak.reason.empty());
  EXPECT_LT(peak.value, 0.4);
}

TEST(MaskedNcc, SearchWindowRestrictsTheShifts) {
  const MaskedScene scene = MakeMaskedScene();
  MaskedNccOptions options;
  options.search_window = ShiftWindow::Around(133, 75, 5);
  const MaskedNccSurface around =
      MaskedNcc(scene.fixed, {}, scene.moving, scene.moving_mask, options);
  EXPECT_EQ(around.shift_x0, 128);
  EXPECT_EQ(around.shift_y0, 70);
  EXPECT_EQ(around.ncc.size(), cv::Size(11, 11));
  const NccPeak found = FindPeak(around);
  EXPECT_TRUE(found.confident) << found.BriefReport();
  EXPECT_EQ(found.shift_x, MaskedScene::kShiftX);
  EXPECT_EQ(found.shift_y, MaskedScene::kShiftY);

  // A window that misses the true shift: the best shift stays inside it, and is no match.
  options.search_window = ShiftWindow{100, 120, 60, 70};
  const MaskedNccSurface away =
      MaskedNcc(scene.fixed, {}, scene.moving, scene.moving_mask, options);
  EXPECT_EQ(away.ncc.size(), cv::Size(21, 11));
  const NccPeak wrong = FindPeak(away);
  EXPECT_TRUE(wrong.found);
  EXPECT_GE(wrong.shift_x, 100);
  EXPECT_LE(wrong.shift_x, 120);
  EXPECT_GE(wrong.shift_y, 60);
  EXPECT_LE(wrong.shift_y, 70);
  EXPECT_FALSE(wrong.confident) << wrong.BriefReport();

  // A window off the image altogether gives an empty surface and no match.
  options.search_window = ShiftWindow{1000, 1010, 0, 10};
  const MaskedNccSurface none =
      MaskedNcc(scene.fixed, {}, scene.moving, scene.moving_mask, options);
  EXPECT_TRUE(none.empty());
  const NccPeak nothing = FindPeak(none);
  EXPECT_FALSE(nothing.found);
  EXPECT_FALSE(nothing.confident);
}

TEST(FindPeak, RefinesAnExactQuadraticPeakAndReportsTheRunnerUp) {
  MaskedNccSurface surface;
  surface.ncc.create(30, 40, CV_32F);
  surface.overlap = cv::Mat(30, 40, CV_32S, cv::Scalar(500));
  surface.shift_x0 = -5;
  surface.shift_y0 = 10;
  // A rotated quadratic bowl peaking at (column 20.3, row 12.6) and a lower bump at (5, 25).
  for (int r = 0; r < 30; ++r) {
    for (int c = 0; c < 40; ++c) {
      const double x = c - 20.3;
      const double y = r - 12.6;
      const double bowl = 0.9 - 0.01 * (x * x + y * y + 0.5 * x * y);
      const double bump = 0.6 - 0.05 * ((c - 5) * (c - 5) + (r - 25) * (r - 25));
      surface.ncc.at<float>(r, c) = static_cast<float>(std::max(bowl, bump));
    }
  }
  surface.ncc.at<float>(0, 0) = kNaNf;
  const NccPeak peak = FindPeak(surface);
  ASSERT_TRUE(peak.found);
  EXPECT_EQ(peak.shift_x, 20 - 5);
  EXPECT_EQ(peak.shift_y, 13 + 10);
  EXPECT_NEAR(peak.subpixel_x, 20.3 - 5, 1e-3);
  EXPECT_NEAR(peak.subpixel_y, 12.6 + 10, 1e-3);
  ASSERT_TRUE(peak.has_second);
  EXPECT_EQ(peak.second_x, 5 - 5);
  EXPECT_EQ(peak.second_y, 25 + 10);
  EXPECT_NEAR(peak.second_value, 0.6, 1e-6);
  EXPECT_NEAR(peak.peak_ratio, peak.value / 0.6, 1e-6);
  EXPECT_NEAR(peak.peak_difference, peak.value - 0.6, 1e-6);
  EXPECT_EQ(peak.overlap, 500);
  EXPECT_FALSE(peak.on_border);
  EXPECT_TRUE(peak.confident) << peak.BriefReport();

  PeakOptions strict;
  strict.min_peak_ratio = 2.0;
  const NccPeak doubtful = FindPeak(surface, strict);
  EXPECT_FALSE(doubtful.confident);
  EXPECT_NE(doubtful.reason.find("min_peak_ratio"), std::string::npos) << doubtful.reason;
}

TEST(FindPeak, AllNaNSurfaceHasNoMatch) {
  MaskedNccSurface surface;
  surface.ncc = cv::Mat(5, 5, CV_32F, cv::Scalar(kNaNf));
  surface.overlap = cv::Mat(5, 5, CV_32S, cv::Scalar(0));
  const NccPeak peak = FindPeak(surface);
  EXPECT_FALSE(peak.found);
  EXPECT_FALSE(peak.confident);
  EXPECT_FALSE(peak.reason.empty());
}

TEST(MaskedNcc, FlatOrTooSmallOverlapGivesNaN) {
  cv::RNG rng(5);
  cv::Mat fixed = RandomTexture(40, 40, 1.0, rng);
  fixed(cv::Rect(0, 0, 20, 40)).setTo(3.0f);  // Left half flat.
  const cv::Mat moving = RandomTexture(8, 8, 1.0, rng);
  const MaskedNccSurface surface = MaskedNcc(fixed, {}, moving, {});
  // Template entirely on the flat half: undefined. Corner overlap of 1 pixel: too small.
  EXPECT_TRUE(std::isnan(surface.ncc.at<float>(5 - surface.shift_y0, 5 - surface.shift_x0)));
  EXPECT_TRUE(std::isnan(surface.ncc.at<float>(0, 0)));
  EXPECT_EQ(surface.overlap.at<std::int32_t>(0, 0), 1);
  EXPECT_TRUE(std::isfinite(surface.ncc.at<float>(5 - surface.shift_y0, 25 - surface.shift_x0)));
}

TEST(MaskedNccOptions, CheckNamesTheFieldAndTheRule) {
  EXPECT_NO_THROW(MaskedNccOptions().Check());
  EXPECT_NO_THROW(PeakOptions().Check());

  MaskedNccOptions fraction;
  fraction.min_overlap_fraction = 1.5;
  std::string message = testing::ErrorMessageOf([&] { fraction.Check(); });
  EXPECT_NE(message.find("min_overlap_fraction"), std::string::npos) << message;
  EXPECT_NE(message.find("[0, 1]"), std::string::npos) << message;

  MaskedNccOptions pixels;
  pixels.min_overlap_pixels = 1;
  message = testing::ErrorMessageOf([&] { pixels.Check(); });
  EXPECT_NE(message.find("min_overlap_pixels"), std::string::npos) << message;

  MaskedNccOptions window;
  window.search_window = ShiftWindow{5, 4, 0, 0};
  message = testing::ErrorMessageOf([&] { window.Check(); });
  EXPECT_NE(message.find("search_window.min_shift_x"), std::string::npos) << message;
  // MaskedNcc checks its options too.
  const cv::Mat image(8, 8, CV_32F, cv::Scalar(1.0f));
  message = testing::ErrorMessageOf([&] { MaskedNcc(image, {}, image, {}, window); });
  EXPECT_NE(message.find("search_window.min_shift_x"), std::string::npos) << message;

  PeakOptions ratio;
  ratio.min_peak_ratio = 0.5;
  message = testing::ErrorMessageOf([&] { ratio.Check(); });
  EXPECT_NE(message.find("min_peak_ratio"), std::string::npos) << message;
  EXPECT_THROW(FindPeak(MaskedNccSurface{}, ratio), Error);
}

TEST(MaskedNcc, RejectsWrongImageAndMaskTypes) {
  const cv::Mat image(8, 8, CV_32F, cv::Scalar(1.0f));
  const cv::Mat bytes(8, 8, CV_8U, cv::Scalar(1));
  std::string message = testing::ErrorMessageOf([&] { MaskedNcc(bytes, {}, image, {}); });
  EXPECT_NE(message.find("fixed image"), std::string::npos) << message;
  EXPECT_NE(message.find("CV_32FC1"), std::string::npos) << message;
  message = testing::ErrorMessageOf([&] { MaskedNcc(image, {}, image, cv::Mat(4, 4, CV_8U)); });
  EXPECT_NE(message.find("moving mask"), std::string::npos) << message;
  message = testing::ErrorMessageOf([&] { MaskedNccNaive(image, {}, cv::Mat(), {}); });
  EXPECT_NE(message.find("moving image is empty"), std::string::npos) << message;
}

TEST(MaskedNcc, PicksDirectSummationForFewShiftsAndFftsForManyWithTheSameSurface) {
  cv::RNG rng(3);
  cv::Mat fixed(300, 300, CV_32F);
  rng.fill(fixed, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(fixed, fixed, cv::Size(), 1.5);
  const cv::Mat moving = fixed(cv::Rect(100, 90, 64, 48)).clone();
  MaskedNccOptions few;
  few.search_window = ShiftWindow::Around(100, 90, 1);
  EXPECT_TRUE(DirectNccIsCheaper(fixed, {}, moving, {}, few));
  MaskedNccOptions many;  // Every shift of a 300 px image.
  EXPECT_FALSE(DirectNccIsCheaper(fixed, {}, moving, {}, many));
  for (const MaskedNccOptions& options : {few, many}) {
    MaskedNccOptions fft = options, direct = options;
    fft.method = NccMethod::kFft;
    direct.method = NccMethod::kDirect;
    const MaskedNccSurface picked = MaskedNcc(fixed, {}, moving, {}, options);
    ExpectSurfacesEqual(picked, MaskedNcc(fixed, {}, moving, {}, fft), 1e-4);
    ExpectSurfacesEqual(picked, MaskedNcc(fixed, {}, moving, {}, direct), 1e-4);
  }
  // No shift to compute: nothing is cheaper, the surface is empty either way.
  MaskedNccOptions outside;
  outside.search_window = ShiftWindow::Around(5000, 5000, 1);
  EXPECT_FALSE(DirectNccIsCheaper(fixed, {}, moving, {}, outside));
  EXPECT_TRUE(MaskedNcc(fixed, {}, moving, {}, outside).empty());
}

// A textured fixed image, the same with 5 % NaN holes, and a template cut from it at `cut` with
// about a fifth of its pixels masked in blobs.
struct HoledScene {
  cv::Mat fixed, holed, moving, moving_mask;
};

HoledScene MakeHoledScene(uint64_t seed, cv::Size size, cv::Rect cut, double sigma) {
  cv::RNG rng(seed);
  HoledScene scene;
  scene.fixed = RandomTexture(size.height, size.width, sigma, rng);
  scene.holed = scene.fixed.clone();
  AddNaNHoles(scene.holed, 0.05, rng);
  scene.moving = scene.fixed(cut).clone();
  scene.moving_mask = RandomMask(cut.height, cut.width, 0.8, rng);
  return scene;
}

// Single-precision transforms: the surface within 1e-4 of the double one (fixed images with and
// without holes, a masked template), and a flat overlap is still undefined, not round-off.
TEST(MaskedNcc, SinglePrecisionTransformsAgreeToOneInTenThousand) {
  const HoledScene scene = MakeHoledScene(5, cv::Size(230, 200), cv::Rect(60, 50, 80, 64), 1.5);
  const cv::Mat &fixed = scene.fixed, &moving = scene.moving, &moving_mask = scene.moving_mask;
  for (const cv::Mat& image : {scene.fixed, scene.holed}) {
    MaskedNccOptions options = Fft({});
    const MaskedNccSurface reference = MaskedNcc(image, {}, moving, moving_mask, options);
    options.fft_precision = FftPrecision::kSingle;
    ExpectSurfacesEqual(MaskedNcc(image, {}, moving, moving_mask, options), reference, 1e-4);
  }
  // A flat patch in a textured image: shifts whose overlap lies in it have no correlation.
  cv::Mat patched = 100.0f * fixed + 1000.0f;  // Bright, strong texture: large round-off.
  patched(cv::Rect(100, 100, 100, 90)).setTo(1050.0f);
  MaskedNccOptions single = Fft({});
  single.fft_precision = FftPrecision::kSingle;
  single.search_window = ShiftWindow::Around(110, 110, 2);
  const cv::Mat small = moving(cv::Rect(0, 0, 40, 40)).clone();
  const MaskedNccSurface flat = MaskedNcc(patched, {}, small, {}, single);
  ASSERT_FALSE(flat.empty());
  for (auto it = flat.ncc.begin<float>(); it != flat.ncc.end<float>(); ++it) {
    EXPECT_TRUE(std::isnan(*it)) << *it;
  }
}

// A template prepared once gives every surface the template itself gives: both routes, an
// all-valid fixed image (the integral images it keeps) and one with holes, several windows.
TEST(MaskedNcc, PreparedTemplateGivesTheSameSurfaces) {
  const HoledScene scene = MakeHoledScene(11, cv::Size(170, 160), cv::Rect(50, 40, 48, 36), 1.2);
  const cv::Mat &moving = scene.moving, &moving_mask = scene.moving_mask;
  const PreparedTemplate prepared(moving, moving_mask);
  EXPECT_EQ(prepared.size(), moving.size());
  for (const cv::Mat& image : {scene.fixed, scene.holed}) {
    for (const NccMethod method : {NccMethod::kDirect, NccMethod::kFft}) {
      for (const ShiftWindow& window :
           {ShiftWindow::Around(50, 40, 1), ShiftWindow::Around(10, 100, 6),
            ShiftWindow::Around(-6, -4, 3)}) {
        MaskedNccOptions options;
        options.min_overlap_fraction = 0.2;  // Shifts off the top-left corner count too.
        options.method = method;
        options.search_window = window;
        const MaskedNccSurface expected = MaskedNcc(image, {}, moving, moving_mask, options);
        const MaskedNccSurface got = MaskedNcc(image, {}, prepared, options);
        ASSERT_FALSE(got.empty());
        ExpectSurfacesEqual(got, expected, 1e-9);
      }
    }
  }
  EXPECT_THROW(PreparedTemplate(cv::Mat(), {}), Error);
}

// The FFT cost estimate that cuts a search into one window or several: four corner tiles of a
// small window reach nearly the same pixels as the whole (one window is cheaper), those of a
// large window a small part of them (the tiles are cheaper).
TEST(MaskedNcc, FftCostEstimateTellsOneWindowFromCornerTiles) {
  const cv::Size templ(155, 85);
  // Four 48 x 48 corner tiles, whatever the window.
  const double tiles = 4.0 * FftNccCostNs(templ, ShiftWindow{0, 47, 0, 47});
  EXPECT_LT(FftNccCostNs(templ, ShiftWindow::Around(0, 0, 60)), tiles);
  EXPECT_GT(FftNccCostNs(templ, ShiftWindow::Around(0, 0, 600)), tiles);
  EXPECT_GT(FftNccCostNs(templ, ShiftWindow::Around(0, 0, 2)), 0.0);
  EXPECT_EQ(FftNccCostNs(templ, ShiftWindow{1, 0, 0, 0}), 0.0);
  EXPECT_EQ(FftNccCostNs(cv::Size(0, 0), ShiftWindow::Around(0, 0, 2)), 0.0);
}

}  // namespace
}  // namespace areomap
