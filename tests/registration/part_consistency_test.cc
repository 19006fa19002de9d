// The template parts' consistency (part_consistency.h): a template that fits as a whole passes,
// one whose quadrants fit at different shifts (a look-alike of part of it) does not, and parts
// without texture say nothing.
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/registration/part_consistency.h"

namespace areomap {
namespace {

// A random texture (uniform noise blurred by 1.2 px), the kind of surface both images show.
cv::Mat Texture(int rows, int cols, uint32_t seed) {
  cv::Mat image(rows, cols, CV_32F);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (auto it = image.begin<float>(); it != image.end<float>(); ++it) *it = u(rng);
  cv::GaussianBlur(image, image, cv::Size(), 1.2);
  return image;
}

// The template of `size` whose pixel (r, c) is the fixed image's at (r + y, c + x), with noise.
cv::Mat Cut(const cv::Mat& fixed, cv::Point shift, cv::Size size, float noise, uint32_t seed) {
  cv::Mat t = fixed(cv::Rect(shift, size)).clone();
  cv::Mat n(size, CV_32F);
  std::mt19937 rng(seed);
  std::normal_distribution<float> gauss(0.0f, noise);
  for (auto it = n.begin<float>(); it != n.end<float>(); ++it) *it = gauss(rng);
  return t + n;
}

MaskedImage HighPassed(const cv::Mat& t) {
  cv::Mat mean;
  cv::GaussianBlur(t, mean, cv::Size(), 3.0);
  return {t - mean, {}};
}

TEST(PartConsistency, ATemplateThatFitsAsAWholeIsConsistent) {
  const cv::Mat fixed = Texture(256, 256, 1);
  const cv::Point truth(70, 60);
  const cv::Mat t = Cut(fixed, truth, cv::Size(96, 80), 0.05f, 2);
  const PartConsistency c = CheckPartConsistency(HighPassed(fixed), HighPassed(t), truth, 16, 0.7);
  EXPECT_TRUE(c.consistent()) << c.Describe();
  EXPECT_EQ(c.tested(), 4);
  for (const PartFit& p : c.parts) {
    EXPECT_LE(std::hypot(p.offset_px.x, p.offset_px.y), 1.0) << p.name;
    EXPECT_GE(p.z(), kMinPartZ) << p.name;
  }
  EXPECT_EQ(c.largest_contradiction(), 0.0);
  EXPECT_EQ(c.Describe(), "");
}

TEST(PartConsistency, QuadrantsThatFitElsewhereContradictTheMatch) {
  // The right half of the template comes from 6 px east and 3 px south of where its left half
  // does: the whole fits at neither; at the left half's shift, the right quadrants fit elsewhere.
  const cv::Mat fixed = Texture(256, 256, 3);
  const cv::Point left(70, 60), right(76, 63);
  const cv::Size size(96, 80);
  cv::Mat t = Cut(fixed, left, size, 0.05f, 4);
  Cut(fixed, right, size, 0.05f, 5)(cv::Rect(48, 0, 48, 80)).copyTo(t(cv::Rect(48, 0, 48, 80)));
  const PartConsistency c = CheckPartConsistency(HighPassed(fixed), HighPassed(t), left, 16, 0.7);
  ASSERT_FALSE(c.consistent());
  const PartFit& worst = c.parts[c.worst];
  EXPECT_TRUE(worst.name == "top-right" || worst.name == "bottom-right") << worst.name;
  EXPECT_EQ(worst.offset_px, right - left);
  EXPECT_GE(worst.contradiction(), kMinContradiction);
  EXPECT_NE(c.Describe().find("quadrant fits best"), std::string::npos) << c.Describe();
  // The left quadrants agree with the match.
  EXPECT_EQ(c.parts[0].offset_px, cv::Point(0, 0));
  EXPECT_EQ(c.parts[2].offset_px, cv::Point(0, 0));
}

TEST(PartConsistency, PartsWithoutTextureOrPixelsAreNotEvidence) {
  const cv::Mat fixed = Texture(256, 256, 6);
  const cv::Point truth(70, 60);
  cv::Mat t = Cut(fixed, truth, cv::Size(96, 80), 0.05f, 7);
  // The top-left quadrant masked out, the bottom-left one pure noise unrelated to the image.
  cv::Mat mask(t.size(), CV_8U, cv::Scalar(255));
  mask(cv::Rect(0, 0, 48, 40)).setTo(0);
  cv::Mat noise(40, 48, CV_32F);
  cv::randn(noise, 0.0, 0.2);
  noise.copyTo(t(cv::Rect(0, 40, 48, 40)));
  MaskedImage hp = HighPassed(t);
  hp.mask = mask;
  const PartConsistency c = CheckPartConsistency(HighPassed(fixed), hp, truth, 16, 0.7);
  EXPECT_TRUE(c.consistent()) << c.Describe();
  EXPECT_FALSE(c.parts[0].tested);
  EXPECT_EQ(c.parts[0].pixels, 0);
  // The noise quadrant has a best shift somewhere, but nothing stands clear of its chance level.
  EXPECT_LT(c.parts[2].z(), kMinPartZ);
  EXPECT_FALSE(c.parts[2].contradicts());
}

TEST(PartConsistency, DegenerateInputGivesUntestedPartsNotExceptions) {
  const cv::Mat fixed = Texture(64, 64, 8);
  // An empty template, one off the image, one without valid pixels.
  EXPECT_EQ(CheckPartConsistency(HighPassed(fixed), {}, {0, 0}, 4, 0.7).tested(), 0);
  const cv::Mat t = Cut(fixed, {8, 8}, cv::Size(32, 32), 0.01f, 9);
  EXPECT_EQ(CheckPartConsistency(HighPassed(fixed), HighPassed(t), {500, 500}, 4, 0.7).tested(), 0);
  const cv::Mat nan(32, 32, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const PartConsistency c = CheckPartConsistency(HighPassed(fixed), {nan, {}}, {8, 8}, 4, 0.7);
  EXPECT_EQ(c.tested(), 0);
  EXPECT_TRUE(c.consistent());
}

}  // namespace
}  // namespace areomap
