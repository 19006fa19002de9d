// Rock extraction from a site's stereo points (ch. 2.2.2): peaks, background plane, height,
// surface points, and the rock models of rock_model.h.
//
// Input: a PointCloud in a site frame (x north, y east, z down [m]); "up" is -z. Steps:
//  1. Peaks: local maxima of elevation in a window (50 x 50 cm) whose elevation range exceeds
//     `min_peak_relief_m` (10 cm) with at least 3 points; peaks farther than `max_peak_range_m`
//     (30 m, Table 4.5) from the camera are dropped. The window is evaluated on a uniform grid of
//     window/5 cells (each cell's highest point is a candidate; the window is the 5 x 5 cells
//     around it), so it is centred within half a cell (5 cm) of the candidate.
//  2. Background plane from the points within `plane_radius_m` (0.7 m, widened to 1.7 H + 0.3 m
//     for large rocks) of the peak, except those nearer than `plane_exclusion_k` times the
//     window's relief (the rock itself; at most half the neighbourhood), fitted by least squares
//     while iteratively dropping the points that stand above it (the rock): a robust fit of the
//     ground. H = peak-to-plane distance.
//  3. Surface points grown from the peak (ch. 2.2.2 steps 2-3): the points above the plane within
//     0.3 H, then repeatedly those within MaxD_Neighbor (largest nearest-neighbour distance of the
//     points found so far) of the last points found, until the radius reaches 1.7 H or nothing is
//     added.
//  4. Models (rocks at least `model_min_height_m` high, after merging): every shape of
//     rock_model.h fitted in the rock frame (origin at the peak's foot on
//     the plane, z along the plane normal, x toward north), best first.
// A peak that lies on the surface of a higher rock, or nearer to a higher peak than that rock's
// reach plus twice the peaks' separation sigma, is merged into it. Neighbour searches use a
// uniform grid (no O(n^2) scans); rocks are processed in parallel (TBB), deterministically.
//
// Failures: a cloud with a non-finite point throws areomap::Error (CheckPointCloud); an empty
// cloud or one without rocks gives an empty list. Per-rock problems (too few points, no model)
// are flags on the rock.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/landmarks/rock_model.h"
#include "areomap/map/point_cloud.h"
#include "areomap/map/progress.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

struct RockExtractionOptions {
  double peak_window_m = 0.5;       // Local-maximum window (50 x 50 cm).
  double min_peak_relief_m = 0.10;  // Elevation range within the window [m].
  int min_window_points = 3;        // Points within the window.
  double max_peak_range_m = 30.0;   // Horizontal distance peak - camera (Table 4.5) [m].
  double plane_radius_m = 0.7;      // Background plane neighbourhood [m] ...
  // ... without the points within k x window relief of the peak (0: all points, the default;
  // 1 lowers the ground's bias under far rocks but admits more borderline rocks, which costs
  // tie-point precision on the long preset: docs/notes/rocks-history.md).
  double plane_exclusion_k = 0.0;
  double min_height_m = 0.10;       // Rocks lower than this above their plane are dropped [m].
  double surface_k_min = 0.3;       // Surface search starts within k_min H of the peak ...
  double surface_k_max = 1.7;       // ... and stops at k_max H.
  double above_plane_m = 0.02;      // A surface point stands this far above the plane [m] ...
  double above_plane_sigmas = 2.0;  // ... or this many of the ground's robust residual sigmas.
  int max_model_points = 80;        // Surface points passed to the model fits (evenly thinned).
  bool fit_models = true;
  // Lower rocks are not modeled: FaultDetectionOptions::min_peak_to_plane_m drops them [m].
  double model_min_height_m = 0.12;
  RockModelFitOptions model;
  void Check() const;  // Throws areomap::Error naming the field.
};

struct ExtractedRock {
  int id = 0;                                      // 1-based, in order of decreasing height.
  int peak_index = -1;                             // Index of the peak in the cloud.
  Eigen::Vector3d peak = Eigen::Vector3d::Zero();  // Site frame [m].
  Eigen::Matrix3d peak_covariance = Eigen::Matrix3d::Zero();
  double range_m = 0.0;   // Horizontal distance from the camera [m].
  double height_m = 0.0;  // Peak to background plane (H) [m].
  Eigen::Vector3d plane_normal = Eigen::Vector3d(0, 0, -1);  // Unit, pointing up, site frame.
  Eigen::Vector3d peak_foot = Eigen::Vector3d::Zero();       // Peak projected on the plane.
  int background_points = 0;
  double ground_sigma_m = 0.0;       // Robust sigma of the ground points about the plane [m].
  std::vector<int> surface_indices;  // Cloud indices of the rock's surface points.
  double surface_radius_m = 0.0;     // Largest horizontal reach of the surface points [m].
  Rigid3d rock_from_site;            // Into the rock frame of rock_model.h.
  std::vector<RockModelFit> models;  // Best (smallest eq. 2.13 RMS) first; empty if not fitted.

  bool modeled() const { return !models.empty() && models.front().converged; }
  const RockModelFit* best_model() const { return modeled() ? &models.front() : nullptr; }
};

struct RockExtractionSummary {
  int points = 0;
  int peak_candidates = 0;  // Local maxima passing relief and count tests.
  int beyond_range = 0;     // Peaks dropped beyond max_peak_range_m.
  int too_low = 0;          // Dropped for H < min_height_m or no fittable ground plane.
  int merged = 0;           // Peaks on a higher rock's surface.
  int rocks = 0;
  int modeled = 0;
};

std::vector<ExtractedRock> ExtractRocks(const PointCloud& cloud,
                                        const RockExtractionOptions& options,
                                        RockExtractionSummary* summary = nullptr,
                                        const ProgressCallback& progress = nullptr);

}  // namespace areomap
