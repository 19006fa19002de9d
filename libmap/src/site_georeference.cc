#include "areomap/map/site_georeference.h"

#include <cmath>
#include <limits>
#include <optional>

#include <tbb/enumerable_thread_specific.h>

#include "areomap/map/error.h"
#include "areomap/map/numbers.h"

namespace areomap {
namespace {

const Eigen::Vector3d kNaN3(kNaN, kNaN, kNaN);

}  // namespace

SiteGeoreference SiteGeoreference::AtOrigin(const Body& body, const Geographic& origin) {
  if (!IsValid(origin)) throw Error("site georeference: the origin is not a valid lat/lon/h");
  return {body, SiteFromMbf(body, origin).Inverse()};
}

SiteGeoreference SiteGeoreference::InMission(const Body& body, const Geographic& mission_origin,
                                             const Rigid3d& mission_from_site) {
  const SiteGeoreference mission = AtOrigin(body, mission_origin);
  return {body, mission.mbf_from_site * mission_from_site};
}

Geographic SiteGeoreference::Origin() const {
  return GeographicFromMbf(body, mbf_from_site.translation);
}

struct MapFrame::Impl {
  Body body;
  std::string wkt;
  std::optional<MapProjection> projection;  // Local equirectangular.
  std::optional<Crs> crs;                   // Any other CRS.
  // OGR transformations are not thread-safe: one per thread.
  mutable tbb::enumerable_thread_specific<std::unique_ptr<CrsTransform>> transforms;

  const CrsTransform& Transform() const {
    std::unique_ptr<CrsTransform>& t = transforms.local();
    if (!t) t = std::make_unique<CrsTransform>(*crs);
    return *t;
  }
};

MapFrame MapFrame::LocalEquirectangular(const Body& body, const Geographic& center) {
  auto impl = std::make_shared<Impl>();
  impl->body = body;
  impl->projection = MapProjection::Equirectangular(body, center.lat, center.lon,
                                                    EquirectangularRadius::kLocalAtCenterLatitude);
  impl->wkt = impl->projection->Wkt();
  return MapFrame(std::move(impl));
}

MapFrame MapFrame::FromCrs(const Body& body, const Crs& crs) {
  crs.RequireMars();
  if (!crs.Describe().is_projected) {
    throw Error(crs.source() + ": a map needs a projected CRS (metres), not a geographic one");
  }
  auto impl = std::make_shared<Impl>();
  impl->body = body;
  impl->crs = crs;
  impl->wkt = crs.Wkt();
  impl->Transform();  // Fails here, not per point, if PROJ cannot transform.
  return MapFrame(std::move(impl));
}

Eigen::Vector3d MapFrame::MapFromMbf(const Eigen::Vector3d& p_in_mbf) const {
  if (!p_in_mbf.allFinite()) return kNaN3;
  const double h = GeographicFromMbf(impl_->body, p_in_mbf).h;
  if (impl_->projection) {
    const Spherical radial = SphericalFromMbf(p_in_mbf);
    const Eigen::Vector2d xy = impl_->projection->Forward({radial.lat, radial.lon, 0.0});
    return {xy.x(), xy.y(), h};
  }
  const std::optional<Eigen::Vector3d> xyz = impl_->Transform().FromMbf(p_in_mbf);
  if (!xyz) return kNaN3;
  return {xyz->x(), xyz->y(), h};
}

Eigen::Vector3d MapFrame::MbfFromMap(const Eigen::Vector3d& p_in_map) const {
  if (!p_in_map.allFinite()) return kNaN3;
  if (impl_->projection) {
    const Geographic g = impl_->projection->Inverse(p_in_map.head<2>());
    return MbfOnRadialLine(impl_->body, g.lat, g.lon, p_in_map.z());
  }
  const std::optional<Eigen::Vector3d> p =
      impl_->Transform().ToMbfAtHeight(p_in_map.head<2>(), impl_->body, p_in_map.z());
  return p ? *p : kNaN3;
}

Eigen::Matrix3d MapFrame::JacobianAt(const Eigen::Vector3d& p_in_mbf) const {
  Eigen::Matrix3d jacobian;
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d step = 0.5 * Eigen::Vector3d::Unit(axis);
    jacobian.col(axis) = MapFromMbf(p_in_mbf + step) - MapFromMbf(p_in_mbf - step);
  }
  return jacobian;
}

const std::string& MapFrame::Wkt() const { return impl_->wkt; }
const Body& MapFrame::body() const { return impl_->body; }

}  // namespace areomap
