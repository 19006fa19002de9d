#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "areomap/crater/learned_detector.h"

namespace areomap {
namespace {

// The scoring rule's tolerance (crater_score.h), the edge rim in the place of the truth: the
// same crater when the centres lie closer than a quarter of the larger diameter and the
// network's diameter is within 30 % of the rim's.
bool SameCrater(const CraterDetection& edge, const CraterDetection& found) {
  const double de = edge.Diameter(), df = found.Diameter();
  if (!(de > 0.0 && df > 0.0)) return false;
  const double ratio = df / de;
  return (edge.ellipse.center - found.ellipse.center).norm() < 0.25 * std::max(de, df) &&
         ratio >= 0.7 && ratio <= 1.3;
}

}  // namespace

std::vector<CraterDetection> MergeEdgeAndLearnedCraters(
    std::vector<CraterDetection> edges, const std::vector<CraterDetection>& learned) {
  const size_t edge_count = edges.size();
  for (const CraterDetection& found : learned) {
    bool known = false;
    for (size_t k = 0; k < edge_count && !known; ++k) {
      if (!SameCrater(edges[k], found)) continue;
      known = true;
      if (!(edges[k].model_score >= found.model_score)) edges[k].model_score = found.model_score;
    }
    if (!known) edges.push_back(found);
  }
  return edges;
}

}  // namespace areomap
