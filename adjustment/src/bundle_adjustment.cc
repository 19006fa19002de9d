#include "areomap/adjustment/bundle_adjustment.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <boost/math/distributions/chi_squared.hpp>

#include <Eigen/Cholesky>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "areomap/map/error.h"
#include "bundle_checks.h"
#include "bundle_costs.h"

namespace areomap {
namespace {

using bundle_internal::AbsolutePointResidual;
using bundle_internal::AbsolutePoseResidual;
using bundle_internal::CheckSite;
using bundle_internal::HeightResidual;
using bundle_internal::ImageResidual;
using bundle_internal::RelativePoseResidual;
using bundle_internal::StereoPointResidual;
using bundle_internal::Whitening;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

double ChiSquareQuantile(int dof, double alpha) {
  return boost::math::quantile(boost::math::chi_squared(static_cast<double>(dof)), 1.0 - alpha);
}

std::array<double, 6> PoseParameters(const Rigid3d& traverse_from_site) {
  std::array<double, 6> p{};
  const Eigen::Quaterniond& q = traverse_from_site.rotation;
  const double wxyz[4] = {q.w(), q.x(), q.y(), q.z()};
  ceres::QuaternionToAngleAxis(wxyz, p.data());
  for (int i = 0; i < 3; ++i) p[3 + i] = traverse_from_site.translation[i];
  return p;
}

Rigid3d PoseFromParameters(const std::array<double, 6>& p) {
  double wxyz[4];
  ceres::AngleAxisToQuaternion(p.data(), wxyz);
  return Rigid3d(Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]),
                 Eigen::Vector3d(p[3], p[4], p[5]));
}

std::string SiteName(int site) {
  char text[16];
  std::snprintf(text, sizeof(text), "s%03d", site);
  return text;
}

// Initial traverse_from_site per site: given, or chained along the priors from site 0.
std::vector<Rigid3d> InitialPoses(const BundleInput& input) {
  if (!input.initial_poses.empty()) return input.initial_poses;
  std::vector<std::optional<Rigid3d>> poses(static_cast<size_t>(input.site_count));
  poses[0] = Rigid3d();
  std::deque<int> queue = {0};
  while (!queue.empty()) {
    const int site = queue.front();
    queue.pop_front();
    for (const RelativePosePrior& p : input.priors) {
      if (p.site_a == site && !poses[static_cast<size_t>(p.site_b)]) {
        poses[static_cast<size_t>(p.site_b)] = *poses[static_cast<size_t>(site)] * p.a_from_b;
        queue.push_back(p.site_b);
      } else if (p.site_b == site && !poses[static_cast<size_t>(p.site_a)]) {
        poses[static_cast<size_t>(p.site_a)] =
            *poses[static_cast<size_t>(site)] * p.a_from_b.Inverse();
        queue.push_back(p.site_a);
      }
    }
  }
  std::vector<Rigid3d> out;
  for (size_t i = 0; i < poses.size(); ++i) {
    if (!poses[i]) {
      throw Error("bundle input: site " + std::to_string(i) +
                  " has no initial pose and no chain of pose priors to site 0");
    }
    out.push_back(*poses[i]);
  }
  return out;
}

// One observation group (what the normalized residual test accepts or rejects as a whole).
struct Group {
  ObservationKind kind = ObservationKind::kTiePoint;
  int index = 0;  // Into the input vector of its kind.
  std::string id;
  std::vector<int> sites;
  int dof = 0;
  bool active = true;
  std::string reason;
  bool outside_window = false;  // Touches no adjusted site: not part of this adjustment.
  std::vector<ceres::ResidualBlockId> blocks;
  std::vector<Eigen::MatrixXd> unwhitening;  // Per block: Cholesky factor L of the covariance.
  std::vector<int> block_image;              // Per block: index of its ImageObservation, or -1.
  std::map<int, std::vector<int>> images_at_site;  // Site -> ImageObservation indices.
};

Group MakeGroup(ObservationKind kind, size_t index, std::string id, std::vector<int> sites,
                int dof) {
  Group g;
  g.kind = kind;
  g.index = static_cast<int>(index);
  g.id = std::move(id);
  g.sites = std::move(sites);
  g.dof = dof;
  return g;
}

class Network {
 public:
  Network(const BundleInput& input, const BundleOptions& options)
      : input_(input), options_(options), initial_(InitialPoses(input)) {
    traverse_from_mbf_ = SiteFromMbf(input.body, input.origin);
    for (const Rigid3d& pose : initial_) poses_.push_back(PoseParameters(pose));
    const int n = input.site_count;
    free_.assign(static_cast<size_t>(n), options.free_sites.empty());
    for (int site : options.free_sites) free_[static_cast<size_t>(site)] = true;
    absolute_ = input.HasAbsoluteObservations();
    if (!absolute_) free_[0] = false;
    for (size_t i = 0; i < input.tie_points.size(); ++i) {
      const TiePoint& t = input.tie_points[i];
      groups_.push_back(MakeGroup(ObservationKind::kTiePoint, i, t.id, {t.site_a, t.site_b}, 3));
      points_.push_back(initial_[static_cast<size_t>(t.site_a)] * t.position_in_a);
    }
    for (size_t i = 0; i < input.control_points.size(); ++i) {
      const ControlPoint& c = input.control_points[i];
      groups_.push_back(MakeGroup(ObservationKind::kControlPoint, i, c.id, {c.site}, 3));
      points_.push_back(traverse_from_mbf_ * c.position_mbf);
    }
    for (size_t i = 0; i < input.priors.size(); ++i) {
      const RelativePosePrior& p = input.priors[i];
      groups_.push_back(MakeGroup(ObservationKind::kPosePrior, i,
                                  "prior " + SiteName(p.site_a) + "-" + SiteName(p.site_b),
                                  {p.site_a, p.site_b}, 6));
    }
    for (size_t i = 0; i < input.heights.size(); ++i) {
      const SiteHeight& h = input.heights[i];
      groups_.push_back(
          MakeGroup(ObservationKind::kHeight, i, "height " + SiteName(h.site), {h.site}, 1));
    }
    // Image observations join their landmark's group and replace its stereo observation at
    // their site: 2 residuals each instead of 3.
    std::map<std::string, size_t> group_of_landmark;
    for (size_t i = 0; i < groups_.size(); ++i) {
      if (groups_[i].kind == ObservationKind::kTiePoint ||
          groups_[i].kind == ObservationKind::kControlPoint) {
        group_of_landmark[groups_[i].id] = i;
      }
    }
    for (size_t i = 0; i < input.image_observations.size(); ++i) {
      const ImageObservation& o = input.image_observations[i];
      Group& g = groups_[group_of_landmark.at(o.landmark_id)];
      std::vector<int>& at_site = g.images_at_site[o.site];
      g.dof += at_site.empty() ? -1 : 2;
      at_site.push_back(static_cast<int>(i));
    }
    // Groups that touch no free site carry no information about the unknowns.
    for (Group& g : groups_) {
      g.outside_window = std::none_of(g.sites.begin(), g.sites.end(),
                                      [&](int s) { return free_[static_cast<size_t>(s)]; });
      g.active = !g.outside_window;
    }
    huber_ = std::make_unique<ceres::HuberLoss>(options.huber_scale);
  }

  BundleResult Run(const ProgressCallback& progress) {
    BundleResult result;
    const auto start = Clock::now();
    std::unique_ptr<ceres::Problem> problem;
    for (int round = 0;; ++round) {
      if (progress && !progress(static_cast<double>(round) / (options_.max_rejection_rounds + 1),
                                "bundle adjustment")) {
        throw Error("bundle adjustment cancelled");
      }
      problem = Build();
      ceres::Solver::Options solver;
      solver.linear_solver_type = options_.dense_schur ? ceres::DENSE_SCHUR : ceres::SPARSE_SCHUR;
      solver.max_num_iterations = options_.max_iterations;
      solver.num_threads = options_.num_threads;
      solver.function_tolerance = 1e-10;
      solver.parameter_tolerance = 1e-10;
      ceres::Solver::Summary summary;
      ceres::Solve(solver, problem.get(), &summary);
      result.iterations += static_cast<int>(summary.iterations.size());
      result.converged = summary.termination_type == ceres::CONVERGENCE;
      result.termination = ceres::TerminationTypeToString(summary.termination_type);
      result.rejection_rounds = round;
      if (round >= options_.max_rejection_rounds || !RejectOutliers(*problem)) break;
    }
    result.solve_seconds = Seconds(start);
    if (progress) progress(1.0, "bundle adjustment");
    Report(*problem, result);
    if (options_.compute_covariance) {
      const auto covariance_start = Clock::now();
      ComputeCovariance(*problem, result);
      result.covariance_seconds = Seconds(covariance_start);
    }
    return result;
  }

 private:
  std::unique_ptr<ceres::Problem> Build() {
    ceres::Problem::Options ownership;
    ownership.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    auto problem = std::make_unique<ceres::Problem>(ownership);
    const auto pose = [&](int site) { return poses_[static_cast<size_t>(site)].data(); };
    for (int s = 0; s < input_.site_count; ++s) problem->AddParameterBlock(pose(s), 6);
    const int tie_count = static_cast<int>(input_.tie_points.size());
    for (Group& g : groups_) {
      g.blocks.clear();
      g.unwhitening.clear();
      g.block_image.clear();
      if (!g.active) continue;
      switch (g.kind) {
        case ObservationKind::kTiePoint: {
          const TiePoint& t = input_.tie_points[static_cast<size_t>(g.index)];
          double* point = points_[static_cast<size_t>(g.index)].data();
          AddSiteObservation(*problem, t.site_a, t.position_in_a, t.covariance_in_a, point, g,
                             "tie point");
          AddSiteObservation(*problem, t.site_b, t.position_in_b, t.covariance_in_b, point, g,
                             "tie point");
          break;
        }
        case ObservationKind::kControlPoint: {
          const ControlPoint& c = input_.control_points[static_cast<size_t>(g.index)];
          double* point = points_[static_cast<size_t>(tie_count + g.index)].data();
          AddSiteObservation(*problem, c.site, c.position_in_site, c.covariance_in_site, point, g,
                             "control point");
          const Eigen::Matrix3d r = traverse_from_mbf_.RotationMatrix();
          const Eigen::Matrix3d covariance = r * c.covariance_mbf * r.transpose();
          const Eigen::Matrix3d w =
              Whitening<3>(covariance, "control point '" + c.id + "' covariance_mbf");
          auto* cost = new ceres::AutoDiffCostFunction<AbsolutePointResidual, 3, 3>(
              new AbsolutePointResidual{traverse_from_mbf_ * c.position_mbf, w});
          g.blocks.push_back(problem->AddResidualBlock(cost, huber_.get(), point));
          g.unwhitening.push_back(covariance.llt().matrixL().toDenseMatrix());
          g.block_image.push_back(-1);
          break;
        }
        case ObservationKind::kPosePrior: {
          const RelativePosePrior& p = input_.priors[static_cast<size_t>(g.index)];
          const Matrix6d w = Whitening<6>(p.covariance, g.id + " covariance");
          auto* cost = new ceres::AutoDiffCostFunction<RelativePoseResidual, 6, 6, 6>(
              new RelativePoseResidual{p.a_from_b, w});
          g.blocks.push_back(
              problem->AddResidualBlock(cost, nullptr, pose(p.site_a), pose(p.site_b)));
          g.unwhitening.push_back(p.covariance.llt().matrixL().toDenseMatrix());
          g.block_image.push_back(-1);
          break;
        }
        case ObservationKind::kHeight: {
          const SiteHeight& h = input_.heights[static_cast<size_t>(g.index)];
          const Rigid3d& at = initial_[static_cast<size_t>(h.site)];
          const Eigen::Vector3d mbf = traverse_from_mbf_.Inverse() * at.translation;
          const Geographic foot = GeographicFromMbf(input_.body, mbf);
          // Up (ellipsoid normal) at the site, in the traverse frame.
          const Eigen::Vector3d up_in_mbf =
              EnuFromMbf(input_.body, foot).rotation.conjugate() * Eigen::Vector3d::UnitZ();
          auto* cost = new ceres::AutoDiffCostFunction<HeightResidual, 1, 6>(
              new HeightResidual{foot.h, at.translation, traverse_from_mbf_.rotation * up_in_mbf,
                                 h.height_m, h.sigma_m});
          g.blocks.push_back(problem->AddResidualBlock(cost, huber_.get(), pose(h.site)));
          g.unwhitening.push_back(Eigen::MatrixXd::Constant(1, 1, h.sigma_m));
          g.block_image.push_back(-1);
          break;
        }
      }
    }
    if (absolute_ && free_[0]) {
      const Matrix6d w = Whitening<6>(input_.site0_prior_covariance, "site0_prior_covariance");
      auto* cost = new ceres::AutoDiffCostFunction<AbsolutePoseResidual, 6, 6>(
          new AbsolutePoseResidual{Rigid3d(), w});
      site0_prior_ = problem->AddResidualBlock(cost, nullptr, pose(0));
    } else {
      site0_prior_ = nullptr;
    }
    for (int s = 0; s < input_.site_count; ++s) {
      if (!free_[static_cast<size_t>(s)]) problem->SetParameterBlockConstant(pose(s));
    }
    return problem;
  }

  // The landmark's observation at `site`: its image observations there if any, else the stereo
  // point.
  void AddSiteObservation(ceres::Problem& problem, int site, const Eigen::Vector3d& observed,
                          const Eigen::Matrix3d& covariance, double* point, Group& g,
                          const char* what) {
    const auto images = g.images_at_site.find(site);
    if (images == g.images_at_site.end()) {
      AddStereo(problem, site, observed, covariance, point, g, what);
      return;
    }
    for (int i : images->second) {
      const ImageObservation& o = input_.image_observations[static_cast<size_t>(i)];
      auto* cost = new ceres::AutoDiffCostFunction<ImageResidual, 2, 6, 3>(
          new ImageResidual{o.camera_in_site, o.pixel, o.sigma_px});
      g.blocks.push_back(problem.AddResidualBlock(cost, huber_.get(),
                                                  poses_[static_cast<size_t>(site)].data(), point));
      g.unwhitening.push_back(Eigen::Matrix2d::Identity() * o.sigma_px);
      g.block_image.push_back(i);
    }
  }

  void AddStereo(ceres::Problem& problem, int site, const Eigen::Vector3d& observed,
                 const Eigen::Matrix3d& covariance, double* point, Group& g, const char* what) {
    const Eigen::Matrix3d w = Whitening<3>(
        covariance, std::string(what) + " '" + g.id + "' covariance in site " + SiteName(site));
    auto* cost = new ceres::AutoDiffCostFunction<StereoPointResidual, 3, 6, 3>(
        new StereoPointResidual{observed, w});
    g.blocks.push_back(problem.AddResidualBlock(cost, huber_.get(),
                                                poses_[static_cast<size_t>(site)].data(), point));
    g.unwhitening.push_back(covariance.llt().matrixL().toDenseMatrix());
    g.block_image.push_back(-1);
  }

  // Squared whitened residual of a group without the loss, and its largest metric residual
  // (the position part [m] of pose priors).
  std::pair<double, double> GroupChi2(ceres::Problem& problem, const Group& g) const {
    double chi2 = 0.0, largest = 0.0;
    for (size_t b = 0; b < g.blocks.size(); ++b) {
      const Eigen::MatrixXd& l = g.unwhitening[b];
      Eigen::VectorXd whitened(l.rows());
      double cost = 0.0;
      problem.EvaluateResidualBlock(g.blocks[b], false, &cost, whitened.data(), nullptr);
      chi2 += 2.0 * cost;
      const Eigen::VectorXd metric = l * whitened;
      largest = std::max(largest, metric.tail(std::min<Eigen::Index>(3, metric.size())).norm());
    }
    return {chi2, largest};
  }

  // Deactivates every non-prior group whose chi2 exceeds its quantile; true if any was.
  bool RejectOutliers(ceres::Problem& problem) {
    bool any = false;
    for (Group& g : groups_) {
      if (!g.active || g.kind == ObservationKind::kPosePrior) continue;
      const double threshold = ChiSquareQuantile(g.dof, options_.rejection_alpha);
      const auto [chi2, metric] = GroupChi2(problem, g);
      if (chi2 <= threshold) continue;
      g.active = false;
      char text[200];
      std::snprintf(text, sizeof(text),
                    "normalized residual test: chi2 %.1f > %.1f (%d dof, alpha %g); residual %.3f",
                    chi2, threshold, g.dof, options_.rejection_alpha, metric);
      g.reason = text;
      any = true;
    }
    return any;
  }

  void Report(ceres::Problem& problem, BundleResult& result) {
    result.sites.resize(static_cast<size_t>(input_.site_count));
    for (int s = 0; s < input_.site_count; ++s) {
      SiteReport& r = result.sites[static_cast<size_t>(s)];
      r.site = s;
      r.initial = initial_[static_cast<size_t>(s)];
      r.adjusted = PoseFromParameters(poses_[static_cast<size_t>(s)]);
      r.held = !free_[static_cast<size_t>(s)];
    }
    double chi2_total = 0.0;
    int residual_count = 0;
    for (const Group& g : groups_) {
      ObservationReport o;
      o.kind = g.kind;
      o.id = g.id;
      o.sites = g.sites;
      o.dof = g.dof;
      o.threshold = ChiSquareQuantile(g.dof, options_.rejection_alpha);
      o.rejected = !g.active && !g.outside_window;
      o.reason = g.reason;
      if (g.active) {
        std::tie(o.chi2, o.residual_m) = GroupChi2(problem, g);
        chi2_total += o.chi2;
        for (ceres::ResidualBlockId id : g.blocks) {
          residual_count += problem.GetCostFunctionForResidualBlock(id)->num_residuals();
        }
        for (int s : g.sites) {
          SiteReport& r = result.sites[static_cast<size_t>(s)];
          if (g.kind == ObservationKind::kTiePoint) ++r.tie_points;
          if (g.kind == ObservationKind::kControlPoint) ++r.control_points;
          if (g.kind == ObservationKind::kHeight) ++r.heights;
        }
      }
      if (o.rejected) ++result.rejected;
      if (g.active || o.rejected) result.observations.push_back(o);
    }
    if (site0_prior_ != nullptr) {
      double cost = 0.0;
      problem.EvaluateResidualBlock(site0_prior_, false, &cost, nullptr, nullptr);
      chi2_total += 2.0 * cost;
      residual_count += 6;
    }
    // Per-image RMS of the accepted image residuals [px].
    std::map<std::string, std::pair<int, double>> per_image;
    for (const Group& g : groups_) {
      if (!g.active) continue;
      for (size_t b = 0; b < g.blocks.size(); ++b) {
        if (g.block_image[b] < 0) continue;
        const ImageObservation& o =
            input_.image_observations[static_cast<size_t>(g.block_image[b])];
        double cost = 0.0;
        problem.EvaluateResidualBlock(g.blocks[b], false, &cost, nullptr, nullptr);
        auto& [count, sum] = per_image[o.image];
        ++count;
        sum += 2.0 * cost * o.sigma_px * o.sigma_px;
      }
    }
    for (const auto& [image, stats] : per_image) {
      result.images.push_back({image, stats.first, std::sqrt(stats.second / stats.first)});
    }
    for (SiteReport& r : result.sites) {
      r.only_priors = r.tie_points == 0 && r.control_points == 0 && r.heights == 0;
    }
    int unknowns = 0;
    for (int s = 0; s < input_.site_count; ++s) unknowns += free_[static_cast<size_t>(s)] ? 6 : 0;
    for (const Group& g : groups_) {
      if (g.active &&
          (g.kind == ObservationKind::kTiePoint || g.kind == ObservationKind::kControlPoint)) {
        unknowns += 3;
      }
    }
    result.redundancy = residual_count - unknowns;
    result.sigma0 = result.redundancy > 0 ? std::sqrt(chi2_total / result.redundancy) : 0.0;
    for (size_t i = 0; i < input_.tie_points.size(); ++i) {
      result.tie_point_positions.push_back(points_[i]);
    }
  }

  // Pose covariance by the Schur complement of the landmarks in J^T J (whitened, robustified),
  // inverted densely: 6 n x 6 n for n free sites.
  void ComputeCovariance(ceres::Problem& problem, BundleResult& result) {
    std::vector<int> free_sites;
    ceres::Problem::EvaluateOptions evaluate;
    for (int s = 0; s < input_.site_count; ++s) {
      if (!free_[static_cast<size_t>(s)]) continue;
      free_sites.push_back(s);
      evaluate.parameter_blocks.push_back(poses_[static_cast<size_t>(s)].data());
    }
    const int pose_dims = 6 * static_cast<int>(free_sites.size());
    const int tie_count = static_cast<int>(input_.tie_points.size());
    for (const Group& g : groups_) {
      if (!g.active) continue;
      int point = -1;
      if (g.kind == ObservationKind::kTiePoint) point = g.index;
      if (g.kind == ObservationKind::kControlPoint) point = tie_count + g.index;
      if (point < 0) continue;
      evaluate.parameter_blocks.push_back(points_[static_cast<size_t>(point)].data());
    }
    const Eigen::MatrixXd inverse = options_.ceres_covariance
                                        ? CeresCovariance(problem, evaluate.parameter_blocks,
                                                          static_cast<int>(free_sites.size()))
                                        : SchurCovariance(problem, evaluate, pose_dims);
    const int n = input_.site_count;
    result.pose_covariance = Eigen::MatrixXd::Zero(6 * n, 6 * n);
    for (size_t a = 0; a < free_sites.size(); ++a) {
      for (size_t b = 0; b < free_sites.size(); ++b) {
        result.pose_covariance.block<6, 6>(6 * free_sites[a], 6 * free_sites[b]) =
            inverse.block<6, 6>(6 * static_cast<Eigen::Index>(a), 6 * static_cast<Eigen::Index>(b));
      }
    }
    for (int s = 0; s < n; ++s) {
      result.sites[static_cast<size_t>(s)].covariance =
          result.pose_covariance.block<6, 6>(6 * s, 6 * s);
    }
  }

  // Inverse of the reduced camera system S = H_pp - H_pl H_ll^-1 H_lp.
  static Eigen::MatrixXd SchurCovariance(ceres::Problem& problem,
                                         const ceres::Problem::EvaluateOptions& evaluate,
                                         int pose_dims) {
    const int pose_blocks = pose_dims / 6;
    const int total =
        pose_dims + 3 * (static_cast<int>(evaluate.parameter_blocks.size()) - pose_blocks);
    ceres::CRSMatrix crs;
    // Non-finite residuals or Jacobians (coordinates beyond what doubles square) leave no matrix.
    if (!problem.Evaluate(evaluate, nullptr, nullptr, nullptr, &crs) || crs.num_cols < total) {
      throw Error(
          "bundle adjustment: the Jacobian at the solution is not finite (a site, prior or "
          "point with coordinates too large to adjust?)");
    }
    Eigen::SparseMatrix<double, Eigen::RowMajor> j(crs.num_rows, crs.num_cols);
    std::vector<Eigen::Triplet<double>> triplets;
    for (int row = 0; row < crs.num_rows; ++row) {
      for (int k = crs.rows[static_cast<size_t>(row)]; k < crs.rows[static_cast<size_t>(row) + 1];
           ++k) {
        triplets.emplace_back(row, crs.cols[static_cast<size_t>(k)],
                              crs.values[static_cast<size_t>(k)]);
      }
    }
    j.setFromTriplets(triplets.begin(), triplets.end());
    const Eigen::SparseMatrix<double> h = Eigen::SparseMatrix<double>(j.transpose()) * j;
    Eigen::MatrixXd schur = Eigen::MatrixXd(h.topLeftCorner(pose_dims, pose_dims));
    for (int c = pose_dims; c < total; c += 3) {
      Eigen::Matrix3d h_ll;
      std::vector<int> rows;
      std::map<int, int> row_index;
      for (int k = 0; k < 3; ++k) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(h, c + k); it; ++it) {
          if (it.row() < pose_dims && !row_index.count(static_cast<int>(it.row()))) {
            row_index[static_cast<int>(it.row())] = static_cast<int>(rows.size());
            rows.push_back(static_cast<int>(it.row()));
          }
        }
      }
      Eigen::MatrixXd b = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()), 3);
      h_ll.setZero();
      for (int k = 0; k < 3; ++k) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(h, c + k); it; ++it) {
          const int row = static_cast<int>(it.row());
          if (row < pose_dims) {
            b(row_index[row], k) = it.value();
          } else if (row >= c && row < c + 3) {
            h_ll(row - c, k) = it.value();
          }
        }
      }
      const Eigen::MatrixXd correction = b * h_ll.ldlt().solve(b.transpose());
      for (size_t r1 = 0; r1 < rows.size(); ++r1) {
        for (size_t r2 = 0; r2 < rows.size(); ++r2) {
          schur(rows[r1], rows[r2]) -=
              correction(static_cast<Eigen::Index>(r1), static_cast<Eigen::Index>(r2));
        }
      }
    }
    // S is banded (a site shares landmarks and priors with its neighbours only): a sparse
    // Cholesky and 6n back-substitutions cost O(n^2 b) instead of a dense O(n^3) inverse.
    const Eigen::SparseMatrix<double> sparse_schur = schur.sparseView(0.0, 1.0);
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(sparse_schur);
    if (ldlt.info() != Eigen::Success) {
      throw Error(
          "bundle adjustment: the reduced normal matrix is singular (a site or the "
          "network has too few observations)");
    }
    return ldlt.solve(Eigen::MatrixXd::Identity(pose_dims, pose_dims));
  }

  static Eigen::MatrixXd CeresCovariance(ceres::Problem& problem,
                                         const std::vector<double*>& blocks, int pose_blocks) {
    ceres::Covariance::Options covariance_options;
    covariance_options.algorithm_type = ceres::SPARSE_QR;
    ceres::Covariance covariance(covariance_options);
    std::vector<std::pair<const double*, const double*>> pairs;
    for (int a = 0; a < pose_blocks; ++a) {
      for (int b = a; b < pose_blocks; ++b) pairs.emplace_back(blocks[a], blocks[b]);
    }
    if (!covariance.Compute(pairs, &problem)) {
      throw Error("bundle adjustment: the network is rank deficient (ceres::Covariance failed)");
    }
    Eigen::MatrixXd out(6 * pose_blocks, 6 * pose_blocks);
    for (int a = 0; a < pose_blocks; ++a) {
      for (int b = a; b < pose_blocks; ++b) {
        Eigen::Matrix<double, 6, 6, Eigen::RowMajor> block;
        covariance.GetCovarianceBlock(blocks[a], blocks[b], block.data());
        out.block<6, 6>(6 * a, 6 * b) = block;
        out.block<6, 6>(6 * b, 6 * a) = block.transpose();
      }
    }
    return out;
  }

  const BundleInput& input_;
  const BundleOptions& options_;
  std::vector<Rigid3d> initial_;
  Rigid3d traverse_from_mbf_;
  std::vector<std::array<double, 6>> poses_;
  std::vector<Eigen::Vector3d> points_;
  std::vector<bool> free_;
  bool absolute_ = false;
  std::vector<Group> groups_;
  std::unique_ptr<ceres::LossFunction> huber_;
  ceres::ResidualBlockId site0_prior_ = nullptr;
};

}  // namespace

BundleResult AdjustBundle(const BundleInput& input, const BundleOptions& options,
                          const ProgressCallback& progress) {
  input.Check();
  options.Check();
  for (int site : options.free_sites) CheckSite(site, input.site_count, "BundleOptions.free_sites");
  Network network(input, options);
  return network.Run(progress);
}

IncrementalBundle::IncrementalBundle(Body body, Geographic origin, BundleOptions options)
    : options_(std::move(options)) {
  input_.body = std::move(body);
  input_.origin = origin;
}

void IncrementalBundle::AddSite(const Rigid3d& initial_traverse_from_site,
                                const std::vector<RelativePosePrior>& priors,
                                const std::vector<TiePoint>& tie_points,
                                const std::vector<ControlPoint>& control_points,
                                const std::vector<SiteHeight>& heights,
                                const std::vector<ImageObservation>& image_observations) {
  input_.initial_poses.push_back(initial_traverse_from_site);
  ++input_.site_count;
  input_.priors.insert(input_.priors.end(), priors.begin(), priors.end());
  input_.tie_points.insert(input_.tie_points.end(), tie_points.begin(), tie_points.end());
  input_.control_points.insert(input_.control_points.end(), control_points.begin(),
                               control_points.end());
  input_.heights.insert(input_.heights.end(), heights.begin(), heights.end());
  input_.image_observations.insert(input_.image_observations.end(), image_observations.begin(),
                                   image_observations.end());
}

BundleResult IncrementalBundle::Adjust(std::vector<int> free_sites) {
  BundleOptions options = options_;
  options.free_sites = std::move(free_sites);
  BundleResult result = AdjustBundle(input_, options);
  for (size_t s = 0; s < result.sites.size(); ++s) {
    input_.initial_poses[s] = result.sites[s].adjusted;
  }
  return result;
}

BundleResult IncrementalBundle::AdjustWindow(int window) {
  RequireOption(window >= 1, "IncrementalBundle window", ">= 1 site");
  std::vector<int> free_sites;
  for (int s = std::max(0, input_.site_count - window); s < input_.site_count; ++s) {
    free_sites.push_back(s);
  }
  return Adjust(free_sites);
}

BundleResult IncrementalBundle::Full() { return Adjust({}); }

}  // namespace areomap
