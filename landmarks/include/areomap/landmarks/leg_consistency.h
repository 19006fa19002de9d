// A traverse's legs tested against each other: is each leg's set of rock tie points as precise
// as the other legs' show the tie covariances to be? (Fault detection across legs, after ch.
// 4.2's per-pair rules; the global test of a leg's adjustment, then data snooping, as in
// geodetic network adjustment.)
//
// A leg's 2D conformal fit (eq. 4.4, FitConformalTransform) estimates the variance factor of
// its tie covariances: chi2 / redundancy. A run's covariances are off by a common factor (eq.
// 4.3 is pessimistic on generated stereo by ~3-4x in variance, docs/rocks.md), so a leg's own
// chi-square test, MatchSitePair's leave-one-out test against 13.8, misses a wrong tie point
// that is many sigmas off by the calibrated covariances. Here the reference is the other legs'
// pooled chi2 / redundancy, and a leg fails when its factor exceeds it by more than the
// F(r_leg, r_reference) quantile at 1 - alpha. Legs that fail are left out of every reference
// (repeated until no further leg fails, so one bad leg does not shield another).
//
// A failing leg's tie points are tested again with the covariances scaled by the reference: the
// one whose leave-one-out chi-square (LeaveOneOutChi2) is largest and above max_residual_chi2
// is dropped, while more than min_tie_points remain, until the leg passes. A leg that still
// fails, or whose remaining tie points have no redundancy left to show that it passes, is
// excluded. A leg that passes is never changed, and the covariances written are never
// scaled: the test only removes tie points, it admits none.
//
// Frames and units: each leg's tie points in its two site frames [m], as MatchSitePair writes
// them (the horizontal parts are used). Failure: bad options throw areomap::Error naming the
// field; a leg without redundancy (fewer than 3 tie points) or without a reference (no other
// leg with redundancy) is not tested.
#pragma once

#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "areomap/landmarks/localization_error.h"
#include "areomap/map/landmark_links.h"

namespace areomap {

struct LegConsistencyOptions {
  double alpha = 0.001;             // False alarm rate of the F test, per leg.
  double max_residual_chi2 = 13.8;  // Leave-one-out chi-square (2 dof, 99.9 %) to drop a tie.
  int min_tie_points = 3;           // Fault detection's minimum (FaultDetectionOptions).
  void Check() const;               // Throws areomap::Error naming the field.
};

struct LegConsistency {
  bool tested = false;
  // The leg's fit on the tie points kept, against the reference (the other legs that pass).
  double sigma0_squared = 0.0;  // chi2 / redundancy at the covariances given.
  int redundancy = 0;
  double reference_sigma0_squared = 0.0;
  int reference_redundancy = 0;
  double f_statistic = 0.0;        // sigma0_squared / reference_sigma0_squared.
  double f_threshold = 0.0;        // F(redundancy, reference_redundancy) quantile at 1 - alpha.
  double first_f_statistic = 0.0;  // Before any tie point was dropped.
  std::vector<int> dropped;        // Indices into the leg's tie points, in the order dropped.
  bool excluded = false;           // Still failing with no tie point left to drop.

  bool Failed() const { return tested && f_statistic > f_threshold; }
  nlohmann::json ToJson() const;
};

// The horizontal part of a tie point, as eq. 4.4 takes it: current = site a, adjacent = site b.
PlanarTiePoint PlanarTie(const TiePoint& tie);

// One verdict per leg, in order. `legs[i]` holds leg i's tie points (empty for a leg that fault
// detection excluded: not tested, and no reference).
std::vector<LegConsistency> TestLegConsistency(const std::vector<std::vector<TiePoint>>& legs,
                                               const LegConsistencyOptions& options = {});

}  // namespace areomap
