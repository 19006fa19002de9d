#include "areomap/registration/edge_verify.h"

#include "areomap/registration/edge_histogram.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "orbital_trial.h"
#include "test_support.h"

namespace areomap {
namespace {

TEST(WorldViewVectors, AreTranslationInvariantAndSeeARotation) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 100.0);
  std::vector<Eigen::Vector2d> a, moved, turned;
  const double t = 10.0 * std::numbers::pi / 180.0;
  Eigen::Matrix2d rot;
  rot << std::cos(t), -std::sin(t), std::sin(t), std::cos(t);
  for (int k = 0; k < 40; ++k) {
    a.emplace_back(u(rng), u(rng));
    moved.push_back(a.back() + Eigen::Vector2d(13.5, -7.25));
    turned.push_back(rot * a.back());
  }
  std::vector<double> dr, dt;
  WorldViewVectorDifferences(a, moved, 5.0, dr, dt);
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_NEAR(dr[k], 0.0, 1e-9);
    EXPECT_NEAR(dt[k], 0.0, 1e-9);
  }
  WorldViewVectorDifferences(a, turned, 5.0, dr, dt);
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_NEAR(dr[k], 0.0, 1e-9);   // Radii do not change under a rotation...
    EXPECT_NEAR(dt[k], 10.0, 1e-9);  // ... every polar angle turns by it.
  }
}

class EdgeVerifyTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    testing::TrialOptions o;
    o.seed = 11;
    o.orbital_half_extent_m = 35.0;
    o.ortho_half_extent_m = 15.0;
    o.telemetry_sigma_m = 2.0;
    o.decoy = false;
    trial_ = new testing::Trial(testing::MakeTrial(o));
    match_ = new OrbitalMatch(MatchOrthoToOrbital(trial_->ortho, *trial_->orbital, trial_->prior));
  }
  static void TearDownTestSuite() {
    delete match_;
    delete trial_;
  }
  static testing::Trial* trial_;
  static OrbitalMatch* match_;
};
testing::Trial* EdgeVerifyTest::trial_ = nullptr;
OrbitalMatch* EdgeVerifyTest::match_ = nullptr;

TEST_F(EdgeVerifyTest, EdgesOfACorrectMatchPairUpAndConfirmIt) {
  ASSERT_TRUE(match_->matched) << match_->BriefReport();
  const EdgeVerification v = VerifyMatchWithEdges(*match_);
  std::printf("edges of a correct match: %s\n", v.BriefReport().c_str());
  EXPECT_GT(v.ortho_edges, 200);
  EXPECT_GT(v.orbital_edges, 200);
  int pairs = 0;
  for (int n : v.pairs_per_group) pairs += n;
  EXPECT_EQ(pairs, static_cast<int>(v.pairs.size()));
  // Table 3.7 found 64.5% of the ground edge points within 3 px of a HiRISE one; under
  // another sun a good part of the edges (shadows) differ, so ask for a third.
  EXPECT_GT(v.ortho_rate, 0.33) << v.BriefReport();
  EXPECT_GT(v.pattern_pairs, 50) << v.BriefReport();
  ASSERT_TRUE(v.fitted);
  EXPECT_TRUE(v.consistent) << v.BriefReport();
  // The match is within 0.5 px; the edge fit's residual shift must agree to a pixel.
  EXPECT_LE(v.shift_px.norm(), 1.0) << v.BriefReport();

  // Fig. 3.15 as a picture: 4 groups x 2 histograms, with ink on it.
  const cv::Mat picture = WorldViewVectorHistogramImage(v);
  EXPECT_EQ(picture.type(), CV_8UC3);
  EXPECT_LT(cv::mean(picture)[0], 254.0);

  EdgeVerificationOptions similarity;
  similarity.fit_similarity = true;
  const EdgeVerification s = VerifyMatchWithEdges(*match_, similarity);
  ASSERT_TRUE(s.fitted) << s.BriefReport();
  EXPECT_LE(s.shift_px.norm(), 1.0) << s.BriefReport();
  EXPECT_NEAR(s.scale, 1.0, 0.02);
  EXPECT_NEAR(s.rotation_rad, 0.0, 1.0 * std::numbers::pi / 180.0);
}

TEST_F(EdgeVerifyTest, AMatchFourPixelsOffIsNotConfirmed) {
  ASSERT_TRUE(match_->matched);
  OrbitalMatch wrong = *match_;
  wrong.shift_px += Eigen::Vector2d(4.0, -2.0);
  const EdgeVerification v = VerifyMatchWithEdges(wrong);
  std::printf("edges of a match (4, -2) px off: %s\n", v.BriefReport().c_str());
  EXPECT_FALSE(v.consistent) << v.BriefReport();
  // The vote sees the offset: the fitted residual undoes it to a pixel.
  EXPECT_LE((v.shift_px - Eigen::Vector2d(-4.0, 2.0)).norm(), 1.0) << v.BriefReport();
  const EdgeVerification right = VerifyMatchWithEdges(*match_);
  EXPECT_LT(v.pairs_per_group[0], right.pairs_per_group[0]) << v.BriefReport();
}

TEST(EdgeVerificationOptions, CheckNamesTheField) {
  EdgeVerificationOptions options;
  options.max_pair_distance_px = 0.0;
  const std::string message = testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("EdgeVerificationOptions.max_pair_distance_px"), std::string::npos);
}

}  // namespace
}  // namespace areomap
