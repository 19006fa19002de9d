// Scoring crater detections against a catalogue of true craters.
//
// Matching rule: a detection matches a truth crater when the centre distance is below half the
// truth radius (0.25 x truth diameter) and the diameter ratio detected / truth is within
// [0.7, 1.3] (+-30 %). Pairs are taken greedily by increasing centre distance / truth radius,
// each crater and each detection used at most once. Both lists are in one frame (pixels, or any
// common unit); diameters are rim diameters (a + b for an ellipse).
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/ellipse.h"

namespace areomap {

struct CraterCircle {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double diameter = 0.0;
};

struct CraterMatchStats {
  double min_diameter = 0.0;  // bin [min, max) by diameter: truth for recall, detection for
  double max_diameter = 0.0;  // precision
  int truth = 0;              // truth craters in the bin
  int detected = 0;           // detections in the bin
  int matched_truth = 0;      // truth craters in the bin that were matched
  int matched_detected = 0;   // detections in the bin that matched
  double precision = 0.0;     // matched_detected / detected (NaN when none detected)
  double recall = 0.0;        // matched_truth / truth (NaN when no truth)
  double f1 = 0.0;
  double median_center_error = 0.0;    // over matched truth in the bin [unit]
  double median_diameter_error = 0.0;  // |D_det / D_truth - 1|, median
};

struct CraterScore {
  CraterMatchStats all;                      // every diameter >= the first bin edge
  std::vector<CraterMatchStats> bins;        // by the given diameter edges
  std::vector<std::pair<int, int>> matches;  // (truth index, detection index)
};

// Scores `detections` against `truth`. `bin_edges` (ascending, >= 2 values; the last may be
// +inf) define the diameter bins; `all` covers [bin_edges.front(), bin_edges.back()).
CraterScore ScoreCraters(const std::vector<CraterCircle>& truth,
                         const std::vector<CraterCircle>& detections,
                         const std::vector<double>& bin_edges);

// Ellipses and detections as the circles the matching rule compares: centre and rim diameter
// a + b.
std::vector<CraterCircle> CirclesOf(const std::vector<Ellipse>& ellipses);
std::vector<CraterCircle> CirclesOf(const std::vector<CraterDetection>& detections);

// Reads a CSV with a header holding columns x_px, y_px and diameter_px (other columns are
// ignored; areomap's craters.csv qualifies). Throws areomap::Error naming the file and line.
std::vector<CraterCircle> ReadCraterCsv(const std::filesystem::path& path);
// Same from a stream; `source` names it in errors.
std::vector<CraterCircle> ReadCraterCsv(std::istream& in, const std::string& source);

}  // namespace areomap
