// Bundle adjustment of a rover traverse (ch. 4.1, eqs. 4.1-4.8; ch. 5.4's future work of putting
// orbital control in the same network), solved with Ceres.
//
// Unknowns: the pose of every site frame in the traverse frame and the position of every
// landmark (tie point or control point ground point) in the traverse frame.
// Observations, each with its own covariance (whitened by its Cholesky factor):
//  - stereo positions of a landmark in a site frame (TiePoint, ControlPoint::position_in_site):
//    the linearized image-measurement model of eqs. 4.1-4.3 (StereoPointCovariance);
//  - orbital positions of control points in MBF (ControlPoint::position_mbf);
//  - relative pose priors between sites from telemetry or visual odometry;
//  - heights of site origins above the ellipsoid, e.g. from an orbital DTM.
//
// Frames: the traverse frame is the MER site frame of site 0 placed at `origin` (x north, y east,
// z down, metres), i.e. traverse_from_mbf = SiteFromMbf(body, origin). A site pose is
// traverse_from_site (Rigid3d naming: p_in_traverse = traverse_from_site * p_in_site). Its 6x6
// covariance is over (rotation vector [rad], translation [m]) of traverse_from_site: near the
// identity the rotation vector is (roll about north, pitch about east, yaw about down).
//
// Gauge: without control points or heights the network only fixes relative poses, so site 0 is
// held at its initial pose (the identity: it defines the frame) and its covariance is zero. With
// control or heights site 0 is free and gets the prior `BundleInput::site0_prior_covariance`.
//
// Robustness: a Huber loss on each observation's Mahalanobis distance (scale
// BundleOptions::huber_scale, in sigmas) during the solve, then normalized residual tests per
// observation group (a tie point, a control point, a prior, a height): chi-square of the whitened
// residuals against the (1 - alpha) quantile for the group's degrees of freedom. Failing groups
// are removed and the problem re-solved; each rejection keeps its reason. Pose priors are tested
// and reported but never removed (they are what keeps a site with no other links in place).
//
// Failure: invalid input (site indices out of range, non-positive-definite covariances, fewer
// than one site) throws areomap::Error naming the observation. Sites with no tie point, control
// point or height keep the pose their priors give and are flagged in the result.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "areomap/map/body.h"
#include "areomap/map/cahvor.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/landmark_links.h"
#include "areomap/map/progress.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Relative pose of site `site_b` in site `site_a`'s frame, e.g. from wheel odometry and the IMU
// or from visual odometry. Covariance over (rotation vector of the error [rad], translation
// [m]), both in site a's frame; the error is a_from_b_measured^-1 * a_from_b_true's rotation.
struct RelativePosePrior {
  int site_a = -1;
  int site_b = -1;
  Rigid3d a_from_b;
  Matrix6d covariance = Matrix6d::Identity();
  std::string source = "telemetry";
};

// Height of a site frame's origin above the body's ellipsoid [m] with its 1 sigma [m].
struct SiteHeight {
  int site = -1;
  double height_m = 0.0;
  double sigma_m = 1.0;
  std::string source = "orbital_dtm";
};

// A landmark (the ground point of the tie point or control point with id `landmark_id`) seen
// at `pixel` (CAHVOR convention: first pixel centre at (0, 0)) by a camera whose model is given
// in the site frame of `site`. Where a landmark has image observations at a site they replace
// its stereo 3D observation there (the same pixels made it): the rigorous image-measurement
// model instead of its linearization (eqs. 4.1-4.3).
struct ImageObservation {
  std::string landmark_id;
  int site = -1;
  CahvorModel camera_in_site;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  double sigma_px = 0.5;  // Matching error, 1 sigma [px].
  std::string image;      // Product name, for the per-image report.
};

// Diagonal pose covariance from sigmas of (rotation about x, y, z [rad]; translation x, y, z [m]).
Matrix6d PoseCovarianceFromSigmas(const Eigen::Vector3d& rotation_sigma_rad,
                                  const Eigen::Vector3d& translation_sigma_m);

// Covariance of a dead-reckoned leg whose horizontal length is off by a relative error of sigma
// `scale_sigma` along the leg (the vertical is taken as exact: inclinometers) and whose heading
// drifts by `heading_sigma_rad` (this leg's increment), as the generator's TelemetryErrorModel:
// translation error s d + drift (z x d) and yaw error drift, fully correlated, plus the variance of
// the model's second-order terms (s^2, s drift, drift^2: a decimetre on a 25 m leg) and the floor
// `floor_sigmas` (added to the diagonal; rotation [rad], translation [m]) for what the
// two-parameter model does not describe.
Matrix6d DeadReckoningCovariance(const Eigen::Vector3d& leg_in_a, double scale_sigma,
                                 double heading_sigma_rad, const Vector6d& floor_sigmas);

struct BundleInput {
  Body body;
  Geographic origin;  // Planetocentric lat, east lon [rad], height [m] of site 0's origin.
  int site_count = 0;
  // Initial traverse_from_site per site (e.g. telemetry). Empty: chained from the priors from
  // site 0 (every site must then be reachable through priors).
  std::vector<Rigid3d> initial_poses;
  std::vector<RelativePosePrior> priors;
  std::vector<TiePoint> tie_points;
  std::vector<ControlPoint> control_points;
  std::vector<SiteHeight> heights;
  std::vector<ImageObservation> image_observations;
  // Prior on site 0's pose (around the identity) when control or heights anchor the network.
  Matrix6d site0_prior_covariance =
      PoseCovarianceFromSigmas(Eigen::Vector3d(1e-3, 1e-3, 0.035), Eigen::Vector3d(50, 50, 50));

  void Check() const;  // Throws areomap::Error naming the offending observation.
  bool HasAbsoluteObservations() const { return !control_points.empty() || !heights.empty(); }
};

struct BundleOptions {
  // Huber scale on the Mahalanobis distance of one observation [sigmas]; sqrt(chi2_3(0.99)).
  double huber_scale = 3.37;
  // Significance of the normalized residual test (per observation group).
  double rejection_alpha = 1e-3;
  int max_rejection_rounds = 5;
  int max_iterations = 100;
  bool compute_covariance = true;
  // Sites whose poses are adjusted; empty = all (site 0 is still held when there is no absolute
  // observation). Other sites stay at their initial poses (sliding-window / incremental mode:
  // their covariance is then conditional on the held sites).
  std::vector<int> free_sites;
  // Linear solver of the Gauss-Newton steps: landmarks eliminated by the Schur complement and
  // the reduced camera system solved sparse (the default) or dense (a baseline for benches).
  bool dense_schur = false;
  // Covariance by ceres::Covariance (sparse QR of the full Jacobian) instead of the Schur
  // complement of the landmarks: a slower reference for tests and benches.
  bool ceres_covariance = false;
  int num_threads = 1;
  void Check() const;  // Throws areomap::Error naming the field.
};

enum class ObservationKind { kTiePoint, kControlPoint, kPosePrior, kHeight };
std::string ToString(ObservationKind kind);

// One observation group and its test after the final solve.
struct ObservationReport {
  ObservationKind kind = ObservationKind::kTiePoint;
  std::string id;
  std::vector<int> sites;
  double chi2 = 0.0;        // Sum of squared whitened residuals (at the final estimate).
  int dof = 0;              // Degrees of freedom of the test (redundancy of the group).
  double threshold = 0.0;   // chi2 quantile (1 - alpha) for dof.
  double residual_m = 0.0;  // Largest residual of one observation: [m], [px] for images.
  bool rejected = false;
  std::string reason;  // Why it was rejected (empty if kept).
};

struct SiteReport {
  int site = 0;
  Rigid3d initial;                         // traverse_from_site before the adjustment.
  Rigid3d adjusted;                        // traverse_from_site after.
  Matrix6d covariance = Matrix6d::Zero();  // See the file comment; zero for held sites.
  bool held = false;                       // Not adjusted (gauge or outside the window).
  int tie_points = 0;                      // Accepted tie points touching the site.
  int control_points = 0;
  int heights = 0;
  bool only_priors = false;  // No tie point, control point or height: flagged.
};

// Image residuals of one image (ImageObservation::image) after the adjustment.
struct ImageReport {
  std::string image;
  int observations = 0;  // Accepted ones.
  double rms_px = 0.0;
};

struct BundleResult {
  std::vector<SiteReport> sites;
  std::vector<ImageReport> images;
  // Full covariance of all site poses (6 per site, site order) for relative uncertainties.
  Eigen::MatrixXd pose_covariance;
  std::vector<Eigen::Vector3d> tie_point_positions;  // Adjusted, traverse frame, input order.
  std::vector<ObservationReport> observations;
  double sigma0 = 0.0;  // sqrt(chi2 of the accepted observations / redundancy).
  int redundancy = 0;
  int rejected = 0;
  int rejection_rounds = 0;
  int iterations = 0;
  bool converged = false;
  std::string termination;
  double solve_seconds = 0.0;
  double covariance_seconds = 0.0;

  // Relative covariance (6x6) of site b's pose minus site a's pose (rotation vector, position).
  Matrix6d RelativeCovariance(int site_a, int site_b) const;
  std::string BriefReport() const;  // A few readable lines.
};

// Adjusts the network. Reports progress per solve round; returning false cancels (throws Error).
BundleResult AdjustBundle(const BundleInput& input, const BundleOptions& options = {},
                          const ProgressCallback& progress = nullptr);

// Incremental use: sites are added one at a time (with their priors and links) and only the
// last `window` sites are adjusted, the earlier ones held at their latest estimates; Full()
// re-adjusts everything.
class IncrementalBundle {
 public:
  IncrementalBundle(Body body, Geographic origin, BundleOptions options = {});
  // Adds the next site (index = current site count) with its initial pose and the observations
  // that link it to earlier sites (or to the orbital frame).
  void AddSite(const Rigid3d& initial_traverse_from_site,
               const std::vector<RelativePosePrior>& priors,
               const std::vector<TiePoint>& tie_points,
               const std::vector<ControlPoint>& control_points,
               const std::vector<SiteHeight>& heights = {},
               const std::vector<ImageObservation>& image_observations = {});
  // Adjusts the last `window` sites; the covariances are then conditional on the held sites.
  BundleResult AdjustWindow(int window);
  BundleResult Full();
  const BundleInput& input() const { return input_; }

 private:
  BundleResult Adjust(std::vector<int> free_sites);
  BundleInput input_;
  BundleOptions options_;
};

nlohmann::json ToJson(const BundleResult& result);

}  // namespace areomap
