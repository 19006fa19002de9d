#include "areomap/map/crs.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

#include <ogr_spatialref.h>

#include "areomap/map/error.h"
#include "gdal_util.h"

namespace areomap {
namespace {

// Mars's radii span ~3376 km (pole) to ~3397 km (equator); local-radius spheres lie between.
constexpr double kMarsMinRadius = 3.30e6;
constexpr double kMarsMaxRadius = 3.45e6;

std::string ExportWkt2(const OGRSpatialReference& srs) {
  char* wkt = nullptr;
  const char* options[] = {"FORMAT=WKT2_2019", "MULTILINE=YES", nullptr};
  if (srs.exportToWkt(&wkt, options) != OGRERR_NONE || wkt == nullptr) {
    CPLFree(wkt);
    throw Error("cannot export CRS to WKT2: " + internal::LastGdalError());
  }
  std::string out(wkt);
  CPLFree(wkt);
  return out;
}

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

OGRSpatialReference FromInputOrThrow(std::string_view text, std::string_view what) {
  internal::EnsureGdalInitialized();
  internal::QuietGdalErrors quiet;
  OGRSpatialReference srs;
  const std::string input(text);
  if (input.empty() || srs.SetFromUserInput(input.c_str()) != OGRERR_NONE) {
    std::string shown = input.size() > 80 ? input.substr(0, 80) + "..." : input;
    throw Error(std::string(what) + " '" + shown +
                "': not a CRS GDAL/PROJ knows (expected e.g. IAU_2015:49910, WKT or a PROJ "
                "string): " +
                internal::LastGdalError());
  }
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

bool IsPlanetocentric(const OGRSpatialReference& geographic, const Body& body) {
  if (body.IsSphere()) return true;
  const std::string wkt = Lower(ExportWkt2(geographic));
  return wkt.find("planetocentric latitude") != std::string::npos ||
         wkt.find("cs[spherical") != std::string::npos;
}

LongitudeDirection LongitudeAxisDirection(const OGRSpatialReference& geographic) {
  for (int i = 0; i < 2; ++i) {
    OGRAxisOrientation orientation = OAO_Other;
    geographic.GetAxis(nullptr, i, &orientation);
    if (orientation == OAO_West) return LongitudeDirection::kWest;
  }
  return LongitudeDirection::kEast;
}

CrsDescription DescribeSrs(const OGRSpatialReference& srs) {
  internal::QuietGdalErrors quiet;
  CrsDescription d;
  d.name = srs.GetName() != nullptr ? srs.GetName() : "";
  const char* authority = srs.GetAuthorityName(nullptr);
  const char* code = srs.GetAuthorityCode(nullptr);
  if (authority != nullptr && code != nullptr) d.authority = std::string(authority) + ":" + code;
  OGRErr err = OGRERR_NONE;
  const double a = srs.GetSemiMajor(&err);
  const double b = srs.GetSemiMinor(&err);
  const char* ellipsoid = srs.GetAttrValue("ELLIPSOID");
  if (ellipsoid == nullptr) ellipsoid = srs.GetAttrValue("SPHEROID");
  d.ellipsoid_name = ellipsoid != nullptr ? ellipsoid : "";
  d.body = Body{d.ellipsoid_name, a, b};
  d.is_mars = (a >= kMarsMinRadius && a <= kMarsMaxRadius) ||
              Lower(d.ellipsoid_name).find("mars") != std::string::npos;
  d.is_projected = srs.IsProjected();
  d.is_geocentric = srs.IsGeocentric();
  std::unique_ptr<OGRSpatialReference> geographic(srs.CloneGeogCS());
  if (geographic != nullptr) {
    d.latitude_type = IsPlanetocentric(*geographic, d.body) ? LatitudeType::kPlanetocentric
                                                            : LatitudeType::kPlanetographic;
    d.longitude_direction = LongitudeAxisDirection(*geographic);
  }
  if (d.is_projected) {
    const char* method = srs.GetAttrValue("PROJECTION");
    d.projection_method = method != nullptr ? method : "";
    const OGR_SRSNode* root = srs.GetAttrNode("PROJCS");
    for (int i = 0; root != nullptr && i < root->GetChildCount(); ++i) {
      const OGR_SRSNode* child = root->GetChild(i);
      if (std::string(child->GetValue()) == "PARAMETER" && child->GetChildCount() >= 2) {
        d.projection_parameters[child->GetChild(0)->GetValue()] =
            std::atof(child->GetChild(1)->GetValue());
      }
    }
  }
  return d;
}

}  // namespace

struct Crs::Impl {
  OGRSpatialReference srs;
};

std::string GeographicCrsWkt(const Body& body) {
  body.Check();
  if (body == Body::MarsSphere()) return ExportWkt2(FromInputOrThrow("IAU_2015:49900", "CRS"));
  if (body == Body::Mars2000()) return ExportWkt2(FromInputOrThrow("IAU_2015:49902", "CRS"));
  internal::EnsureGdalInitialized();
  OGRSpatialReference srs;
  const std::string name = body.IsSphere() ? body.name : body.name + " (planetographic)";
  srs.SetGeogCS(name.c_str(), ("D_" + body.name).c_str(), body.name.c_str(), body.a,
                body.InverseFlattening(), "Reference_Meridian", 0.0);
  return ExportWkt2(srs);
}

std::string ProjectedCrsWkt(const Body& body, std::string_view method,
                            const std::map<std::string, double>& parameters) {
  const auto parameter = [&](const char* key) {
    const auto it = parameters.find(key);
    if (it == parameters.end()) {
      throw Error("projection " + std::string(method) + ": missing parameter " + key);
    }
    return DegFromRad(it->second);
  };
  const OGRSpatialReference base = FromInputOrThrow(GeographicCrsWkt(body), "CRS");
  OGRSpatialReference srs;
  srs.SetProjCS((body.name + " / " + std::string(method)).c_str());
  srs.CopyGeogCSFrom(&base);
  OGRErr err = OGRERR_NONE;
  if (method == "Equirectangular") {
    err = srs.SetEquirectangular2(0.0, parameter("center_lon"), parameter("center_lat"), 0.0, 0.0);
  } else if (method == "Sinusoidal") {
    err = srs.SetSinusoidal(parameter("center_lon"), 0.0, 0.0);
  } else if (method == "PolarStereographic") {
    err = srs.SetPS(parameter("center_lat"), parameter("center_lon"), 1.0, 0.0, 0.0);
  } else {
    throw Error("unknown projection method '" + std::string(method) +
                "': expected Equirectangular, Sinusoidal or PolarStereographic");
  }
  if (err != OGRERR_NONE) {
    throw Error("cannot build " + std::string(method) + " CRS: " + internal::LastGdalError());
  }
  srs.SetLinearUnits(SRS_UL_METER, 1.0);
  return ExportWkt2(srs);
}

Crs Crs::FromUserInput(std::string_view text) {
  auto impl = std::make_shared<Impl>();
  impl->srs = FromInputOrThrow(text, "unknown CRS");
  return Crs(std::move(impl), std::string(text));
}

Crs Crs::FromWkt(std::string_view wkt, std::string_view source) {
  auto impl = std::make_shared<Impl>();
  impl->srs = FromInputOrThrow(wkt, std::string(source) + ": unreadable CRS");
  return Crs(std::move(impl), std::string(source));
}

std::string Crs::Wkt() const { return ExportWkt2(impl_->srs); }

CrsDescription Crs::Describe() const { return DescribeSrs(impl_->srs); }

void Crs::RequireMars() const {
  const CrsDescription d = Describe();
  if (!d.is_mars) {
    std::ostringstream msg;
    msg.precision(10);
    msg << source_ << ": CRS '" << d.name << "' is not on Mars (ellipsoid '" << d.ellipsoid_name
        << "', a = " << d.body.a << " m): expected a Mars CRS (a between " << kMarsMinRadius
        << " and " << kMarsMaxRadius << " m, e.g. IAU_2015:49900)";
    throw Error(msg.str());
  }
}

struct CrsTransform::Impl {
  OGRSpatialReference srs;
  std::unique_ptr<OGRSpatialReference> geographic;
  std::unique_ptr<OGRCoordinateTransformation> to_geographic;    // Projected only.
  std::unique_ptr<OGRCoordinateTransformation> from_geographic;  // Projected only.
  GeographicConvention convention;
  bool geocentric = false;
};

CrsTransform::CrsTransform(const Crs& crs) : impl_(std::make_unique<Impl>()) {
  internal::QuietGdalErrors quiet;
  impl_->srs = crs.impl_->srs;
  impl_->srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  description_ = DescribeSrs(impl_->srs);
  impl_->geocentric = impl_->srs.IsGeocentric();
  impl_->convention.latitude = description_.latitude_type;
  impl_->convention.longitude = description_.longitude_direction;
  if (impl_->geocentric) return;
  impl_->geographic.reset(impl_->srs.CloneGeogCS());
  if (impl_->geographic == nullptr) {
    throw Error(crs.source() + ": CRS has no geographic base CRS: " + internal::LastGdalError());
  }
  impl_->geographic->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (impl_->srs.IsProjected()) {
    impl_->to_geographic.reset(
        OGRCreateCoordinateTransformation(&impl_->srs, impl_->geographic.get()));
    impl_->from_geographic.reset(
        OGRCreateCoordinateTransformation(impl_->geographic.get(), &impl_->srs));
    if (impl_->to_geographic == nullptr || impl_->from_geographic == nullptr) {
      throw Error(crs.source() +
                  ": PROJ cannot invert this projection: " + internal::LastGdalError());
    }
  }
}

CrsTransform::~CrsTransform() = default;
CrsTransform::CrsTransform(CrsTransform&&) noexcept = default;
CrsTransform& CrsTransform::operator=(CrsTransform&&) noexcept = default;

std::optional<Eigen::Vector2d> CrsTransform::ToOwnGeographic(const Eigen::Vector2d& xy) const {
  if (!xy.allFinite() || impl_->geocentric) return std::nullopt;
  double x = xy.x(), y = xy.y();
  if (impl_->to_geographic != nullptr) {
    internal::QuietGdalErrors quiet;
    if (!impl_->to_geographic->Transform(1, &x, &y)) return std::nullopt;
  }
  if (!std::isfinite(x) || !std::isfinite(y) || std::abs(y) > 90.0) return std::nullopt;
  return Eigen::Vector2d(x, y);
}

std::optional<Geographic> CrsTransform::ToPlanetocentric(const Eigen::Vector2d& xy) const {
  const auto lon_lat = ToOwnGeographic(xy);
  if (!lon_lat) return std::nullopt;
  const Geographic own{RadFromDeg(lon_lat->y()), RadFromDeg(lon_lat->x()), 0.0};
  return ConvertGeographic(description_.body, own, impl_->convention, GeographicConvention{});
}

std::optional<Eigen::Vector3d> CrsTransform::ToMbf(const Eigen::Vector3d& xyz) const {
  if (impl_->geocentric) return xyz.allFinite() ? std::optional(xyz) : std::nullopt;
  const auto lon_lat = ToOwnGeographic(xyz.head<2>());
  if (!lon_lat || !std::isfinite(xyz.z())) return std::nullopt;
  const Geographic own{RadFromDeg(lon_lat->y()), RadFromDeg(lon_lat->x()), xyz.z()};
  return MbfFromGeographic(description_.body, own, impl_->convention);
}

std::optional<Eigen::Vector3d> CrsTransform::ToMbfAtHeight(const Eigen::Vector2d& xy,
                                                           const Body& body, double h) const {
  // Walk the line, parametrised by the CRS's own height, to the point at height h above the
  // body: heights along it change at ~1 m/m, so fixed-point steps converge.
  const auto on_line = [&](double t) { return ToMbf({xy.x(), xy.y(), t}); };
  double t = h;
  std::optional<Eigen::Vector3d> p = on_line(t);
  for (int i = 0; i < 4 && p; ++i) {
    const double error = GeographicFromMbf(body, *p).h - h;
    if (std::abs(error) < 1e-6) break;
    t -= error;
    p = on_line(t);
  }
  return p;
}

std::optional<Eigen::Vector3d> CrsTransform::FromMbf(const Eigen::Vector3d& p_in_mbf) const {
  if (!p_in_mbf.allFinite()) return std::nullopt;
  if (impl_->geocentric) return p_in_mbf;
  const Geographic own = GeographicFromMbf(description_.body, p_in_mbf, impl_->convention);
  double x = DegFromRad(own.lon), y = DegFromRad(own.lat);
  if (impl_->from_geographic != nullptr) {
    internal::QuietGdalErrors quiet;
    if (!impl_->from_geographic->Transform(1, &x, &y)) return std::nullopt;
  }
  if (!std::isfinite(x) || !std::isfinite(y)) return std::nullopt;
  return Eigen::Vector3d(x, y, own.h);
}

}  // namespace areomap
