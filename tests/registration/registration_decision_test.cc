// The registration decision (OrbitalMatchOptions::max_false_match, peak_significance.h): the
// chance level of a correlation peak, on Gaussian fields where the answer is known, on a subset
// of the real-image evaluation set (eval/registration_cases.h), and on bad input.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/registration/orbital_match.h"
#include "areomap/registration/peak_significance.h"
#include "orbital_trial.h"
#include "registration_cases.h"
#include "test_support.h"

namespace areomap {
namespace {

// A smooth stationary Gaussian field: white noise blurred by a Gaussian of `sigma_px`, cropped
// from a larger one so that no border (where a reflected kernel doubles the variance) is in it.
cv::Mat SmoothField(int size, double sigma_px, std::mt19937& rng) {
  const int margin = static_cast<int>(std::ceil(5.0 * sigma_px));
  cv::Mat field(size + 2 * margin, size + 2 * margin, CV_32F);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  for (auto it = field.begin<float>(); it != field.end<float>(); ++it) *it = gauss(rng);
  cv::GaussianBlur(field, field, cv::Size(), sigma_px);
  return field(cv::Rect(margin, margin, size, size)).clone();
}

TEST(PeakSignificance, TheMaximumOfPureNoiseIsAsLikelyAsStated) {
  // Under the null the stated probability of the field's own maximum is (about) uniform: a
  // threshold alpha accepts (about) alpha of the fields.
  std::mt19937 rng(7);
  int below_1 = 0, below_5 = 0, below_10 = 0;
  constexpr int kFields = 300;
  for (int k = 0; k < kFields; ++k) {
    const cv::Mat field = SmoothField(96, 2.0, rng);
    double max = 0.0;
    cv::minMaxLoc(field, nullptr, &max);
    // The null measured on another stretch of the same field (as the matcher measures it at
    // wrong shifts), large enough that its own sampling error is small.
    const cv::Mat other = SmoothField(256, 2.0, rng);
    const SurfaceNull null =
        MeasureSurfaceNull(other, cv::Mat(other.size(), CV_8U, cv::Scalar(255)));
    const PeakSignificance s = SignificanceOfPeak(max, null, field.cols, field.rows);
    below_1 += s.false_match_probability <= 0.01;
    below_5 += s.false_match_probability <= 0.05;
    below_10 += s.false_match_probability <= 0.1;
  }
  // The Euler characteristic approximates the probability in its tail (small alpha), where a
  // threshold matters; binomial 3 sigma bounds around alpha.
  EXPECT_LE(below_1, 0.03 * kFields) << below_1;
  EXPECT_GE(below_5, 0.015 * kFields) << below_5;
  EXPECT_LE(below_5, 0.09 * kFields) << below_5;
  EXPECT_GE(below_10, 0.05 * kFields) << below_10;
  EXPECT_LE(below_10, 0.16 * kFields) << below_10;
}

TEST(PeakSignificance, HigherPeaksSmallerWindowsAndFewerWarpsAreLessLikelyByChance) {
  std::mt19937 rng(3);
  const cv::Mat field = SmoothField(80, 1.5, rng);
  const SurfaceNull null = MeasureSurfaceNull(field, cv::Mat(field.size(), CV_8U, cv::Scalar(1)));
  ASSERT_TRUE(null.valid());
  EXPECT_GT(null.lambda_x, 0.0);
  const double p =
      SignificanceOfPeak(null.mean + 4.5 * null.stddev, null, 80, 80).false_match_probability;
  EXPECT_LT(SignificanceOfPeak(null.mean + 5.5 * null.stddev, null, 80, 80).false_match_probability,
            p);
  EXPECT_LT(SignificanceOfPeak(null.mean + 4.5 * null.stddev, null, 20, 20).false_match_probability,
            p);
  EXPECT_GT(
      SignificanceOfPeak(null.mean + 4.5 * null.stddev, null, 80, 80, 11).false_match_probability,
      p);
  // No null (a flat surface), a peak below the mean, a NaN peak: probability 1.
  const cv::Mat flat(40, 40, CV_32F, cv::Scalar(0.3f));
  EXPECT_FALSE(MeasureSurfaceNull(flat, cv::Mat(flat.size(), CV_8U, cv::Scalar(1))).valid());
  EXPECT_EQ(SignificanceOfPeak(0.9, SurfaceNull{}, 80, 80).false_match_probability, 1.0);
  EXPECT_EQ(SignificanceOfPeak(null.mean - 0.1, null, 80, 80).false_match_probability, 1.0);
  EXPECT_EQ(SignificanceOfPeak(std::nan(""), null, 80, 80).false_match_probability, 1.0);
}

// The subset of the evaluation set a test can afford: two images of each family, one case of
// each kind, prior sigmas of 20 and 40 m, one generated scene.
eval::CaseOptions SubsetOptions() {
  eval::CaseOptions o;
  o.seed = 5;
  o.max_images_per_family = 2;
  o.prior_sigmas_m = {20.0, 40.0};
  o.generated_trials = 1;
  return o;
}

TEST(RegistrationDecision, AcceptsRealPositivesWithinAPixelAndRefusesRealNegatives) {
  SKIP_WITHOUT_SHARED_DATA();
  const OrbitalMatchOptions match;
  const std::vector<eval::CaseResult> results =
      eval::RunRealImageCases(testing::SharedDataDir(), SubsetOptions(), match);
  int positives = 0, within = 0, wrong = 0, negatives = 0, false_accepts = 0;
  for (const eval::CaseResult& r : results) {
    EXPECT_EQ(r.matched, r.AcceptedAt(match.max_false_match)) << r.image << " " << r.kind;
    if (r.positive) {
      ++positives;
      within += r.matched && r.error_px <= 1.0;
      wrong += r.matched && !(r.error_px <= 1.0);
    } else {
      ++negatives;
      false_accepts += r.matched;
      EXPECT_FALSE(r.matched) << r.image << " " << r.kind << ": p " << r.false_match_probability
                              << ", CC " << r.correlation;
    }
  }
  ASSERT_GE(positives, 20);
  ASSERT_GE(negatives, 20);
  EXPECT_GE(within, 0.95 * positives) << within << " of " << positives;
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(false_accepts, 0);
}

TEST(RegistrationDecision, MaxFalseMatchMovesAcceptanceAsTheStatedProbabilitySays) {
  // One generated scene: its positives and decoys, matched at a loose and a strict threshold.
  // Each case is accepted exactly when its stated probability is at most the threshold, so
  // the threshold moves acceptance along the reliability curve; at 1 every non-structural case
  // is accepted, the decoys included.
  eval::CaseOptions o = SubsetOptions();
  for (const double alpha : {1e-9, 1e-3, 1.0}) {
    OrbitalMatchOptions match;
    match.max_false_match = alpha;
    const std::vector<eval::CaseResult> results = eval::RunGeneratedCases(o, match);
    ASSERT_EQ(results.size(), 4u);
    int accepted_negatives = 0;
    for (const eval::CaseResult& r : results) {
      EXPECT_EQ(r.matched, r.AcceptedAt(alpha)) << r.kind << " at " << alpha;
      if (!r.positive) accepted_negatives += r.matched;
      if (r.positive && alpha == 1e-3) {
        EXPECT_TRUE(r.matched) << r.kind << ": " << r.reason;
        EXPECT_LE(r.error_px, 1.0) << r.kind;
      }
    }
    if (alpha < 1.0) {
      EXPECT_EQ(accepted_negatives, 0) << alpha;
    } else {
      EXPECT_GT(accepted_negatives, 0);
    }
  }
}

// Bad input: each is refused with a reason, never a crash or an accepted match.
class BadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::TrialOptions o;
    o.seed = 3;
    o.decoy = false;
    trial_ = testing::MakeTrial(o);
  }
  OrbitalMatch Match(const OrthoImage& ortho) const {
    return MatchOrthoToOrbital(ortho, *trial_.orbital, trial_.prior);
  }
  testing::Trial trial_;
};

TEST_F(BadInput, TheTrialItselfRegisters) {
  const OrbitalMatch m = Match(trial_.ortho);
  EXPECT_TRUE(m.matched) << m.BriefReport();
}

TEST_F(BadInput, ATemplateWithoutTextureIsRefused) {
  OrthoImage flat = trial_.ortho;
  flat.image.setTo(cv::Scalar(100.0f));
  const OrbitalMatch m = Match(flat);
  EXPECT_FALSE(m.matched);
  EXPECT_FALSE(m.reason.empty());
}

TEST_F(BadInput, AWindowWithoutOverlapIsRefused) {
  OrbitalPrior far = trial_.prior;
  far.position.lon += 0.01;  // ~590 m east of a 100 m orbital image.
  OrthoImage moved = trial_.ortho;
  moved.geotransform.c[0] += 590.0;
  const OrbitalMatch m = MatchOrthoToOrbital(moved, *trial_.orbital, far);
  EXPECT_FALSE(m.matched);
  EXPECT_NE(m.reason.find("does not overlap"), std::string::npos) << m.reason;
}

TEST_F(BadInput, AMaskHiding99PercentIsRefused) {
  OrthoImage masked = trial_.ortho;
  cv::Mat keep(masked.image.size(), CV_8U, cv::Scalar(0));
  cv::circle(keep, {keep.cols / 2 + 20, keep.rows / 2}, keep.cols / 20, cv::Scalar(255),
             cv::FILLED);
  cv::bitwise_and(masked.mask, keep, masked.mask);
  ASSERT_LT(cv::countNonZero(masked.mask), 0.01 * static_cast<double>(masked.image.total()));
  const OrbitalMatch m = Match(masked);
  EXPECT_FALSE(m.matched) << m.BriefReport();
  EXPECT_FALSE(m.reason.empty());
}

TEST_F(BadInput, NanPixelsAreInvalidNotFatal) {
  // NaN over half the orthophoto: the rest still registers, and no NaN reaches the answer.
  OrthoImage holes = trial_.ortho;
  holes.image(cv::Rect(0, 0, holes.image.cols / 2, holes.image.rows))
      .setTo(std::numeric_limits<float>::quiet_NaN());
  const OrbitalMatch m = Match(holes);
  EXPECT_TRUE(std::isfinite(m.false_match_probability));
  if (m.matched) {
    EXPECT_TRUE(m.shift_en_m.allFinite());
  }
  // An orthophoto of NaN only: refused with a reason.
  OrthoImage none = trial_.ortho;
  none.image.setTo(std::numeric_limits<float>::quiet_NaN());
  const OrbitalMatch n = Match(none);
  EXPECT_FALSE(n.matched);
  EXPECT_FALSE(n.reason.empty());
}

}  // namespace
}  // namespace areomap
