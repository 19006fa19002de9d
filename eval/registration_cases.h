// The registration decision's evaluation set: labelled positives (the template's place is in the
// search window) and negatives (it is not), built deterministically from a seed, from real
// orbital images in ../shared/data and from the generator, and run through MatchOrthoToOrbital.
//
// Real images (CTX MC-11E, HRSC Nanedi Vallis tiles, the MOC crop) are given a Mars
// equirectangular grid (IAU_2015:49910) of `orbital_gsd_m`; a template ("rover orthophoto") is
// cut from one place of the image at a finer GSD and changed by one kind of perturbation, then
// searched for around a telemetry position off by a Gaussian error of the prior's sigma
// (positives), or around a position on the same image so far away that no shift of the window
// shows the template's place (negatives). Kinds:
//   radiometric  gamma 0.6-1.6, gain 0.5-2, offset, noise 2-5 % of the range
//   gsd          the template at 1/4-1/12 of the orbital GSD (cubic), camera blur and noise
//   blur         a wider MTF: Gaussian of 1-2 orbital px
//   wedge        a rover's fan: 90-200 degrees from 3 m out, with occlusion blobs
//   ring         a ring (inner radius 15-40 m) with holes
// Generated (tests/registration/orbital_trial.h): the rover orthophoto under a second sun
// (0.1 m, fan mask) against the 0.25 m orbital image (`second-sun`), and a hillshade of the 1 m
// orbital DTM lit as the orbital image (its sun known to +-10 degrees) against it (`hillshade`,
// cross-modal); negatives search the decoy scene on the same grid.
//
// Frames and units: errors are in orbital pixels, from where the match puts the rover to its
// true pixel.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "areomap/registration/orbital_match.h"

namespace areomap::eval {

struct CaseOptions {
  uint32_t seed = 1;
  int cases_per_image = 1;          // Positives (and as many negatives) per kind and image, >= 1.
  int max_images_per_family = 0;    // 0 = every image of a family (ctx 12, hrsc 5, moc 1).
  double orbital_gsd_m = 1.0;       // Pixel size given to the real images [m], > 0.
  double template_radius_m = 80.0;  // The template's reliable range [m], > 0.
  // Prior sigmas drawn from [m] (the window is +-3 sigma); larger ones are skipped where the
  // image cannot hold a negative's window.
  std::vector<double> prior_sigmas_m = {20.0, 40.0, 80.0};
  std::vector<std::string> kinds = {"radiometric", "gsd", "blur", "wedge", "ring"};
  int generated_trials = 4;  // Generated scenes (each a positive and a negative per kind).

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

struct CaseResult {
  std::string family;  // "ctx", "hrsc", "moc" or "generated".
  std::string kind;    // See the header comment.
  std::string image;   // Source image file name, or the generated seed.
  bool positive = false;
  double prior_sigma_m = 0.0;
  bool matched = false;   // Accepted under the match options given.
  double error_px = 0.0;  // Positives: rover error [orbital px]; NaN for negatives.
  double false_match_probability = 1.0;
  double correlation = 0.0;
  double peak_z = 0.0;
  SurfaceNull null;    // The null statistics behind false_match_probability.
  int null_level = 0;  // Their pyramid level.
  int search_radius_px = 0;
  double part_contradiction = 0.0;  // OrbitalMatch::part_contradiction.
  // Refused for a reason the false-match threshold does not move (a border peak, no chance
  // level): such a case is refused at every threshold.
  bool structural_refusal = false;
  std::string reason;

  // Accepted at false-match threshold `alpha`, the other rules as they were.
  bool AcceptedAt(double alpha) const {
    return !structural_refusal && false_match_probability <= alpha;
  }
};

// Runs the real-image cases of `options` on the images under `data_dir` (the shared data folder).
// Throws areomap::Error if the options fail Check() or an image cannot be read.
std::vector<CaseResult> RunRealImageCases(const std::filesystem::path& data_dir,
                                          const CaseOptions& options,
                                          const OrbitalMatchOptions& match = {});

// Runs the generated cases (second-sun and hillshade positives, decoy negatives).
std::vector<CaseResult> RunGeneratedCases(const CaseOptions& options,
                                          const OrbitalMatchOptions& match = {});

// CSV (one line per case, with a header).
std::string CaseResultsCsv(const std::vector<CaseResult>& results);

}  // namespace areomap::eval
