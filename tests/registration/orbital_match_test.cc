#include "areomap/registration/orbital_match.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "orbital_trial.h"
#include "test_support.h"

namespace areomap {
namespace {

using testing::MakeTrial;
using testing::Trial;
using testing::TrialOptions;

TEST(OrbitalMatch, Explore) {
  for (uint32_t seed = 1; seed <= 6; ++seed) {
    TrialOptions o;
    o.seed = seed;
    auto t0 = std::chrono::steady_clock::now();
    const Trial trial = MakeTrial(o);
    auto t1 = std::chrono::steady_clock::now();
    const OrbitalMatch m = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
    auto t2 = std::chrono::steady_clock::now();
    const OrbitalMatch d = MatchOrthoToOrbital(trial.ortho, *trial.decoy, trial.prior);
    const Eigen::Vector2d err = m.shift_en_m + trial.telemetry_error_en_m;
    std::printf(
        "seed %u render %.2fs match %.3fs err %.3f %.3f m (%.2f px) sig %.3f | %s\n  decoy %s\n",
        seed, std::chrono::duration<double>(t1 - t0).count(),
        std::chrono::duration<double>(t2 - t1).count(), err.x(), err.y(), err.norm() / trial.gsd_m,
        std::sqrt(m.shift_covariance_en_m2(0, 0)), m.BriefReport().c_str(),
        d.BriefReport().c_str());
  }
}

}  // namespace
}  // namespace areomap
