// When two measured rims are one crater: the scoring rule's diameter tolerance (crater_score.h,
// +-30 %) with a reference rim in the place of the truth, and centres within a quarter of the
// larger diameter. Used where two detections of one crater must
// be recognised: the combined detector (an edge rim and the network's find) and the catalogue
// merge (detections from overlapping images, crater_catalogue_merge.h).
//
// Frame: any one frame shared by both circles (pixels of one image, or metres of one map CRS);
// diameters are rim diameters (a + b for an ellipse). Non-positive or NaN diameters are never the
// same crater.
#pragma once

#include "areomap/crater/crater_score.h"

namespace areomap {

// `other` is `reference` when their centres lie closer than a quarter of the larger diameter and
// other's diameter is within [0.7, 1.3] x reference's.
bool SameCrater(const CraterCircle& reference, const CraterCircle& other);

// Either way round (SameCrater(a, b) or SameCrater(b, a)): centres closer than a quarter of the
// larger diameter, smaller / larger diameter >= 0.7. Symmetric, for two detections of which
// neither is the reference.
bool SameCraterEitherWay(const CraterCircle& a, const CraterCircle& b);

// Two detections of one crater as SuppressDuplicateCraters (crater_detector.h) judges them: the
// same rim (centres within half the smaller radius, radii within 30 %), or a concentric inner
// edge (floor, shadow) of it (centres within half the larger radius, radii within a factor 1.6).
// Symmetric.
bool SameCraterOrConcentric(const CraterCircle& a, const CraterCircle& b);
// The largest centre distance at which a circle of `diameter` can be SameCraterOrConcentric with
// another of any diameter: a search radius.
double SameCraterOrConcentricSearchRadius(double diameter);

// The largest centre distance at which a circle of `diameter` can be SameCraterEitherWay with
// another (whose diameter is at most diameter / 0.7): a spatial index's search radius.
double SameCraterSearchRadius(double diameter);

}  // namespace areomap
