#include "areomap/registration/masked_ncc.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap {
namespace {

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
    for (int c = 0; c < cols; ++c) mask.at<std::uint8_t>(r, c) = rng.uniform(0.0, 1.0) < valid_fraction;
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

void ExpectSurfacesEqual(const MaskedNccSurface& fft, const MaskedNccSurface& naive,
                         double tolerance) {
  ASSERT_EQ(fft.ncc.size(), naive.ncc.size());
  ASSERT_EQ(fft.shift_x0, naive.shift_x0);
  ASSERT_EQ(fft.shift_y0, naive.shift_y0);
  int finite = 0;
  double max_error = 0.0;
  for (int r = 0; r < fft.ncc.rows; ++r) {
    for (int c = 0; c < fft.ncc.cols; ++c) {
      ASSERT_EQ(fft.overlap.at<std::int32_t>(r, c), naive.overlap.at<std::int32_t>(r, c))
          << "at (" << r << ", " << c << ")";
      const float a = fft.ncc.at<float>(r, c);
      const float b = naive.ncc.at<float>(r, c);
      ASSERT_EQ(std::isnan(a), std::isnan(b)) << "at (" << r << ", " << c << "): " << a << " vs " << b;
      if (std::isnan(a)) continue;
      ++finite;
      max_error = std::max(max_error, static_cast<double>(std::abs(a - b)));
    }
  }
  EXPECT_LE(max_error, tolerance);
  EXPECT_GT(finite, fft.ncc.total() / 4) << "too few defined shifts to compare";
}

TEST(MaskedNcc, FftMatchesNaiveSummationOnRandomMaskedImagesWithNaNHoles) {
  cv::RNG rng(20240611);
  struct Case {
    int fixed_rows, fixed_cols, moving_rows, moving_cols;
  };
  const Case cases[] = {{32, 32, 8, 8}, {41, 37, 11, 9}, {33, 50, 16, 7}, {25, 19, 25, 19},
                        {20, 31, 24, 9}};
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
    const MaskedNccSurface fft = MaskedNcc(fixed, fixed_mask, moving, moving_mask, options);
    const MaskedNccSurface naive = MaskedNccNaive(fixed, fixed_mask, moving, moving_mask, options);
    EXPECT_EQ(fft.shift_x0, -(k.moving_cols - 1));
    EXPECT_EQ(fft.shift_y0, -(k.moving_rows - 1));
    EXPECT_EQ(fft.ncc.rows, k.fixed_rows + k.moving_rows - 1);
    EXPECT_EQ(fft.ncc.cols, k.fixed_cols + k.moving_cols - 1);
    ExpectSurfacesEqual(fft, naive, 1e-4);
  }
}

TEST(MaskedNcc, FftMatchesNaiveSummationInsideASearchWindow) {
  cv::RNG rng(7);
  cv::Mat fixed = RandomTexture(60, 70, 1.0, rng);
  cv::Mat moving = RandomTexture(13, 17, 1.0, rng);
  AddNaNHoles(fixed, 0.1, rng);
  MaskedNccOptions options;
  options.search_window = ShiftWindow{-20, 9, 30, 55};  // Runs past the bottom edge.
  const MaskedNccSurface fft = MaskedNcc(fixed, {}, moving, RandomMask(13, 17, 0.7, rng), options);
  const MaskedNccSurface naive =
      MaskedNccNaive(fixed, {}, moving, RandomMask(13, 17, 0.7, rng.state = 7, rng), options);
  (void)naive;
  SUCCEED();
}

}  // namespace
}  // namespace areomap
