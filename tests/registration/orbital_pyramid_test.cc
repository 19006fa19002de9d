// The masked pyramid (orbital_pyramid.h) against its definition: a Gaussian of sigma 0.7 px then
// a 2 x 2 mean, both over valid pixels only, written with OpenCV's own filters.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/registration/orbital_pyramid.h"

namespace areomap {
namespace {

struct Reference {
  cv::Mat value;   // Normalized: blurred value / blurred weight.
  cv::Mat weight;  // The blurred, averaged validity.
};

Reference Definition(const MaskedImage& level) {
  cv::Mat valid = level.image == level.image;
  if (!level.mask.empty()) valid &= (level.mask != 0);
  const int rows = level.image.rows + level.image.rows % 2;
  const int cols = level.image.cols + level.image.cols % 2;
  cv::Mat value(rows, cols, CV_32F, cv::Scalar(0.0f)), weight(rows, cols, CV_32F, cv::Scalar(0.0f));
  const cv::Rect inner(0, 0, level.image.cols, level.image.rows);
  level.image.copyTo(value(inner), valid);
  valid.convertTo(weight(inner), CV_32F, 1.0 / 255.0);
  cv::GaussianBlur(value, value, cv::Size(), 0.7, 0.7, cv::BORDER_CONSTANT);
  cv::GaussianBlur(weight, weight, cv::Size(), 0.7, 0.7, cv::BORDER_CONSTANT);
  Reference out;
  cv::resize(value, out.value, cv::Size(cols / 2, rows / 2), 0, 0, cv::INTER_AREA);
  cv::resize(weight, out.weight, cv::Size(cols / 2, rows / 2), 0, 0, cv::INTER_AREA);
  cv::divide(out.value, out.weight, out.value);
  return out;
}

TEST(DownsampleMasked, EqualsTheBlurAndMeanOverValidPixels) {
  cv::RNG rng(4);
  for (const cv::Size size : {cv::Size(97, 64), cv::Size(64, 51), cv::Size(300, 211)}) {
    cv::Mat image(size, CV_32F);
    rng.fill(image, cv::RNG::UNIFORM, 0.0, 100.0);
    image(cv::Rect(10, 12, 7, 5)).setTo(std::numeric_limits<float>::quiet_NaN());
    image.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
    cv::Mat mask(size, CV_8U, cv::Scalar(255));
    mask(cv::Rect(30, 20, 15, 11)).setTo(0);
    const MaskedImage level{image, mask};
    const MaskedImage half = DownsampleMasked(level, 0.75);
    const Reference expected = Definition(level);
    ASSERT_EQ(half.image.size(), expected.value.size());
    int valid = 0;
    for (int r = 0; r < half.image.rows; ++r) {
      for (int c = 0; c < half.image.cols; ++c) {
        const float w = expected.weight.at<float>(r, c);
        if (std::abs(w - 0.75f) < 1e-5f) continue;  // On the threshold: either way.
        const bool expect_valid = w >= 0.75f;
        ASSERT_EQ(half.mask.at<uchar>(r, c) != 0, expect_valid) << "at (" << c << ", " << r << ")";
        if (!expect_valid) {
          EXPECT_TRUE(std::isnan(half.image.at<float>(r, c)));
          continue;
        }
        EXPECT_NEAR(half.image.at<float>(r, c), expected.value.at<float>(r, c), 1e-3f);
        ++valid;
      }
    }
    EXPECT_GT(valid, half.image.total() / 2);
  }
}

TEST(BuildMaskedPyramid, HalvesEachLevelRoundingUp) {
  const cv::Mat image(101, 64, CV_32F, cv::Scalar(3.0f));
  const std::vector<MaskedImage> pyramid = BuildMaskedPyramid({image, {}}, 3);
  ASSERT_EQ(pyramid.size(), 4u);
  EXPECT_EQ(pyramid[1].image.size(), cv::Size(32, 51));
  EXPECT_EQ(pyramid[3].image.size(), cv::Size(8, 13));
  // A constant image stays constant where its pixels are valid (away from the zero border).
  EXPECT_NEAR(pyramid[2].image.at<float>(12, 8), 3.0f, 1e-5f);
}

}  // namespace
}  // namespace areomap
