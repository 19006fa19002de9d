#include "areomap/adjustment/traverse_priors.h"

#include "areomap/map/error.h"

namespace areomap {

Vector6d DefaultDeadReckoningFloor() {
  Vector6d floor;
  floor << 1e-3, 1e-3, 1e-4, 0.02, 0.02, 0.02;
  return floor;
}

std::vector<RelativePosePrior> DeadReckonedPriors(const std::vector<Rigid3d>& traverse_from_site,
                                                  double scale_sigma, double heading_sigma_rad,
                                                  const Vector6d& floor_sigmas,
                                                  const std::string& source) {
  RequireOption(scale_sigma >= 0.0, "DeadReckonedPriors scale_sigma", ">= 0");
  RequireOption(heading_sigma_rad >= 0.0, "DeadReckonedPriors heading_sigma_rad", ">= 0 rad");
  RequireOption((floor_sigmas.array() >= 0.0).all(), "DeadReckonedPriors floor_sigmas",
                ">= 0 each");
  std::vector<RelativePosePrior> priors;
  for (size_t k = 1; k < traverse_from_site.size(); ++k) {
    RelativePosePrior prior;
    prior.site_a = static_cast<int>(k - 1);
    prior.site_b = static_cast<int>(k);
    prior.a_from_b = traverse_from_site[k - 1].Inverse() * traverse_from_site[k];
    prior.covariance = DeadReckoningCovariance(prior.a_from_b.translation, scale_sigma,
                                               heading_sigma_rad, floor_sigmas);
    prior.source = source;
    priors.push_back(prior);
  }
  return priors;
}

}  // namespace areomap
