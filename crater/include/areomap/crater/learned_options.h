// Options of the learned crater detector (learned_detector.h) and the choice of detector, apart
// so that CraterDetectorOptions can hold them.
#pragma once

#include <string>

namespace areomap {

enum class CraterMethod {
  // Images: both detectors, every edge-detector rim the network also sees plus each network
  // crater the edges did not find (MergeEdgeAndLearnedCraters, learned_detector.h); DTMs use the
  // edges.
  kCombined,
  kLearned,  // images: the trained network, rims refined by ellipse fits (learned_detector.h)
  kEdges,    // rim edges -> arcs -> ellipses (crater_detector.h); DTMs always use this
};
// "combined" / "learned" / "edges"; CraterMethodFromString throws areomap::Error for another
// name.
std::string ToString(CraterMethod method);
CraterMethod CraterMethodFromString(const std::string& name);

struct LearnedDetectorOptions {
  std::string model_path;  // ONNX file of a model trained as the built-in one; empty: built-in
  // Heat-map peak threshold in (0, 1): the built-in model's value maximises F1 on its three
  // held-out CTX validation images (docs/crater-model.md).
  double min_score = 0.4;
  // Refit each detection's rim as an ellipse where it has edges (RefineCrater); otherwise, and
  // when false, the crater keeps the network's circle (CraterDetection::rim_fitted false).
  bool refine_rims = true;
  // Combined method: an edge-detector rim is kept only where the network sees the same crater
  // (SameCraterOrConcentric, same_crater.h) with a heat-map peak of at least this score, or where
  // the rim is wider than the network's coarsest pyramid level holds. Edge rims on rough
  // crater-free terrain have no such peak (docs/crater-model.md). 0 keeps every rim; a value over
  // min_score acts as min_score.
  double edge_support_score = 0.1;
  int tile_size = 1024;  // core edge of a pyramid level's tile [px of that level], >= 64

  void Check() const;  // throws areomap::Error naming the bad field
};

}  // namespace areomap
