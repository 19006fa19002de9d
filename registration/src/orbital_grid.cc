#include "areomap/registration/orbital_grid.h"

#include <limits>
#include <map>

namespace areomap {
namespace {

const Eigen::Vector2d kNaN2(std::numeric_limits<double>::quiet_NaN(),
                            std::numeric_limits<double>::quiet_NaN());

// Building a CRS transform costs PROJ a database search (~0.1 s); a registration builds
// several for the same two CRSs. Each thread keeps the ones it built (transforms are not
// shared across threads).
std::shared_ptr<CrsTransform> TransformFor(const std::string& wkt, const std::string& name) {
  thread_local std::map<std::string, std::shared_ptr<CrsTransform>> cache;
  const auto found = cache.find(wkt);
  if (found != cache.end()) return found->second;
  const Crs crs = Crs::FromWkt(wkt, name);
  crs.RequireMars();
  auto transform = std::make_shared<CrsTransform>(crs);
  if (cache.size() > 64) cache.clear();
  cache.emplace(wkt, transform);
  return transform;
}

}  // namespace

PixelGrid::PixelGrid(const GeoTransform& geotransform, const std::string& crs_wkt,
                     const std::string& name)
    : geotransform_(geotransform), crs_wkt_(crs_wkt), name_(name) {
  transform_ = TransformFor(crs_wkt, name);
}

std::optional<Geographic> PixelGrid::PixelToGeographic(const Eigen::Vector2d& pixel) const {
  return transform_->ToPlanetocentric(geotransform_.PixelToMap(pixel.x(), pixel.y()));
}

Eigen::Vector2d PixelGrid::GeographicToPixel(const Geographic& g) const {
  return PointToPixel(MbfFromGeographic(body(), {g.lat, g.lon, 0.0}));
}

Eigen::Vector2d PixelGrid::PointToPixel(const Eigen::Vector3d& p_in_mbf) const {
  const auto xyz = transform_->FromMbf(p_in_mbf);
  if (!xyz) return kNaN2;
  return geotransform_.MapToPixel(xyz->x(), xyz->y());
}

std::optional<Eigen::Vector3d> PixelGrid::PixelToPoint(const Eigen::Vector2d& pixel,
                                                       const Body& body, double h) const {
  return transform_->ToMbfAtHeight(geotransform_.PixelToMap(pixel.x(), pixel.y()), body, h);
}

Eigen::Matrix2d PixelGrid::EastNorthPerPixel(const Eigen::Vector2d& pixel) const {
  Eigen::Matrix2d out = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  const auto origin = PixelToGeographic(pixel);
  if (!origin) return out;
  const Rigid3d enu_from_mbf = EnuFromMbf(body(), *origin);
  for (int k = 0; k < 2; ++k) {
    const auto g = PixelToGeographic(pixel + Eigen::Vector2d::Unit(k));
    if (!g) return out;
    const Eigen::Vector3d enu = enu_from_mbf * MbfFromGeographic(body(), *g);
    out.col(k) = enu.head<2>();
  }
  return out;
}

GridMapping::GridMapping(const PixelGrid& from, const PixelGrid& to)
    : from_(from), to_(to), same_crs_(from.crs_wkt() == to.crs_wkt()) {}

Eigen::Vector2d GridMapping::Apply(const Eigen::Vector2d& from_pixel) const {
  if (same_crs_) {
    const Eigen::Vector2d map = from_.geotransform().PixelToMap(from_pixel.x(), from_pixel.y());
    return to_.geotransform().MapToPixel(map.x(), map.y());
  }
  const auto g = from_.PixelToGeographic(from_pixel);
  if (!g) return kNaN2;
  return to_.GeographicToPixel(*g);
}

}  // namespace areomap
