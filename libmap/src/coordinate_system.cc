#include "areomap/map/coordinate_system.h"

#include <cassert>
#include <cmath>
#include <sstream>
#include <vector>

#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/raster.h"

namespace areomap {
namespace {

enum class Kind { kMbf, kGeographic, kSpherical, kEnu, kSite, kCrs, kPixel };

std::vector<std::string> SplitComma(std::string_view text) {
  std::vector<std::string> out;
  std::string current;
  for (char c : text) {
    if (c == ',') {
      out.push_back(current);
      current.clear();
    } else {
      current += c;
    }
  }
  out.push_back(current);
  return out;
}

std::string Format(double value) {
  std::ostringstream out;
  out.precision(12);
  out << value;
  return out.str();
}

void CheckLatitudeDeg(double lat_deg) {
  if (!std::isfinite(lat_deg) || std::abs(lat_deg) > 90.0) {
    throw Error("latitude " + Format(lat_deg) + " is outside [-90, 90] degrees");
  }
}

void CheckFinite(const Eigen::Vector3d& v) {
  if (!v.allFinite()) {
    throw Error("value (" + Format(v.x()) + ", " + Format(v.y()) + ", " + Format(v.z()) +
                ") is not finite");
  }
}

}  // namespace

struct CoordinateSystem::Impl {
  Kind kind = Kind::kMbf;
  Body body;
  GeographicConvention convention;
  Rigid3d local_from_mbf;
  std::unique_ptr<CrsTransform> crs;
  GeoTransform geotransform;  // kPixel only.
};

std::optional<Body> CoordinateSystem::DatumBody() const {
  if (!impl_->crs) return std::nullopt;
  return impl_->crs->description().body;
}

bool CoordinateSystem::UsesBody() const {
  return impl_->kind == Kind::kGeographic || impl_->kind == Kind::kEnu ||
         impl_->kind == Kind::kSite;
}

CoordinateSystem::CoordinateSystem(std::unique_ptr<Impl> impl, std::string spec)
    : impl_(std::move(impl)), spec_(std::move(spec)) {}
CoordinateSystem::~CoordinateSystem() = default;
CoordinateSystem::CoordinateSystem(CoordinateSystem&&) noexcept = default;
CoordinateSystem& CoordinateSystem::operator=(CoordinateSystem&&) noexcept = default;

CoordinateSystem CoordinateSystem::Parse(std::string_view spec,
                                         const CoordinateSystemContext& context) {
  context.body.Check();
  auto impl = std::make_unique<Impl>();
  impl->body = context.body;
  const std::vector<std::string> parts = SplitComma(spec);
  const std::string& head = parts.front();
  const auto require_origin = [&]() {
    if (!context.origin) {
      throw Error("coordinate system '" + std::string(spec) +
                  "' needs an origin: expected --origin LAT,LON[,H] (planetocentric degrees, m)");
    }
    if (!IsValid(*context.origin)) throw Error("origin latitude is outside [-90, 90] degrees");
    return *context.origin;
  };
  if (head == "mbf") {
    impl->kind = Kind::kMbf;
  } else if (head == "planetocentric" || head == "planetographic") {
    impl->kind = Kind::kGeographic;
    impl->convention.latitude = LatitudeTypeFromString(head);
    for (size_t i = 1; i < parts.size(); ++i) {
      if (parts[i] == "west" || parts[i] == "east") {
        impl->convention.longitude = LongitudeDirectionFromString(parts[i]);
      } else if (parts[i] == "360" || parts[i] == "180") {
        impl->convention.domain = LongitudeDomainFromString(parts[i]);
      } else {
        throw Error("coordinate system '" + std::string(spec) + "': unknown modifier '" + parts[i] +
                    "': expected west, east, 360 or 180");
      }
    }
  } else if (head == "spherical") {
    impl->kind = Kind::kSpherical;
  } else if (head == "enu") {
    impl->kind = Kind::kEnu;
    impl->local_from_mbf = EnuFromMbf(context.body, require_origin());
  } else if (head == "site") {
    impl->kind = Kind::kSite;
    impl->local_from_mbf = SiteFromMbf(context.body, require_origin());
  } else if (spec.starts_with("raster:") || spec.starts_with("pixel:")) {
    const bool pixel = spec.starts_with("pixel:");
    const std::string path(spec.substr(pixel ? 6 : 7));
    const RasterDataset dataset = RasterDataset::Open(path);
    if (dataset.info().crs_wkt.empty() || !dataset.info().geotransform) {
      throw Error(path + ": has no georeference: expected a map-projected raster");
    }
    const Crs crs = Crs::FromWkt(dataset.info().crs_wkt, path);
    crs.RequireMars();
    impl->kind = pixel ? Kind::kPixel : Kind::kCrs;
    impl->crs = std::make_unique<CrsTransform>(crs);
    impl->geotransform = *dataset.info().geotransform;
  } else {
    const Crs crs = Crs::FromUserInput(spec);
    crs.RequireMars();
    impl->kind = Kind::kCrs;
    impl->crs = std::make_unique<CrsTransform>(crs);
  }
  return CoordinateSystem(std::move(impl), std::string(spec));
}

Eigen::Vector3d CoordinateSystem::ToMbf(const Eigen::Vector3d& v) const {
  CheckFinite(v);
  switch (impl_->kind) {
    case Kind::kMbf:
      return v;
    case Kind::kGeographic:
      CheckLatitudeDeg(v.x());
      return MbfFromGeographic(impl_->body, Geographic{RadFromDeg(v.x()), RadFromDeg(v.y()), v.z()},
                               impl_->convention);
    case Kind::kSpherical:
      CheckLatitudeDeg(v.x());
      if (v.z() < 0.0) throw Error("radius " + Format(v.z()) + " is negative");
      return MbfFromSpherical(Spherical{RadFromDeg(v.x()), RadFromDeg(v.y()), v.z()});
    case Kind::kEnu:
    case Kind::kSite:
      return impl_->local_from_mbf.Inverse() * v;
    case Kind::kCrs:
    case Kind::kPixel: {
      Eigen::Vector3d in_crs = v;
      if (impl_->kind == Kind::kPixel) {
        in_crs.head<2>() = impl_->geotransform.PixelToMap(v.x(), v.y());
      } else if (impl_->crs->description().IsGeographic()) {
        CheckLatitudeDeg(v.y());
      }
      const auto mbf = impl_->crs->ToMbf(in_crs);
      if (!mbf) {
        throw Error("(" + Format(v.x()) + ", " + Format(v.y()) +
                    ") is outside the domain of the CRS");
      }
      return *mbf;
    }
  }
  return v;
}

Eigen::Vector3d CoordinateSystem::FromMbf(const Eigen::Vector3d& p) const {
  CheckFinite(p);
  switch (impl_->kind) {
    case Kind::kMbf:
      return p;
    case Kind::kGeographic: {
      const Geographic g = GeographicFromMbf(impl_->body, p, impl_->convention);
      return {DegFromRad(g.lat), DegFromRad(g.lon), g.h};
    }
    case Kind::kSpherical: {
      const Spherical s = SphericalFromMbf(p);
      return {DegFromRad(s.lat), DegFromRad(s.lon), s.radius};
    }
    case Kind::kEnu:
    case Kind::kSite:
      return impl_->local_from_mbf * p;
    case Kind::kCrs:
    case Kind::kPixel: {
      auto out = impl_->crs->FromMbf(p);
      if (!out) throw Error("point cannot be represented in " + spec_);
      if (impl_->kind == Kind::kPixel) {
        out->head<2>() = impl_->geotransform.MapToPixel(out->x(), out->y());
      }
      return *out;
    }
  }
  return p;
}

int CoordinateSystem::Decimals(int component) const {
  const bool angular = (impl_->kind == Kind::kGeographic || impl_->kind == Kind::kSpherical) ||
                       (impl_->kind == Kind::kCrs && impl_->crs->description().IsGeographic());
  if (impl_->kind == Kind::kPixel && component < 2) return 6;
  return (angular && component < 2) ? 12 : 6;
}

CoordinateConversion CoordinateConversion::Make(std::string_view from_spec,
                                                std::string_view to_spec,
                                                CoordinateSystemContext context, bool body_given) {
  CoordinateConversion conversion{CoordinateSystem::Parse(from_spec, context),
                                  CoordinateSystem::Parse(to_spec, context), std::nullopt, ""};
  CoordinateSystem& from = conversion.from;
  CoordinateSystem& to = conversion.to;
  const std::optional<Body> datum = from.DatumBody() ? from.DatumBody() : to.DatumBody();
  if (!body_given && datum && (from.UsesBody() || to.UsesBody()) &&
      (datum->a != context.body.a || datum->b != context.body.b)) {
    context.body = *datum;
    // Only the systems shaped by the body change (no raster is opened again).
    if (from.UsesBody()) from = CoordinateSystem::Parse(from_spec, context);
    if (to.UsesBody()) to = CoordinateSystem::Parse(to_spec, context);
    conversion.datum_body = datum;
    conversion.datum_source = from.DatumBody() ? from.spec() : to.spec();
  }
  return conversion;
}

Eigen::Vector3d CoordinateConversion::Convert(const Eigen::Vector3d& value) const {
  return to.FromMbf(from.ToMbf(value));
}

namespace {

// The line before its `#` comment, with commas and tabs turned into blanks.
std::string PointLineFields(const std::string& line) {
  std::string cleaned = line.substr(0, line.find('#'));
  for (char& c : cleaned) {
    if (c == ',' || c == '\t') c = ' ';
  }
  return cleaned;
}

}  // namespace

bool PointLineIsEmpty(const std::string& line) {
  return PointLineFields(line).find_first_not_of(" \r") == std::string::npos;
}

Eigen::Vector3d ParsePointLine(const std::string& line, int min_numbers) {
  assert(min_numbers == 2 || min_numbers == 3);
  std::istringstream in(PointLineFields(line));
  std::vector<double> values;
  std::string token;
  while (in >> token) {
    try {
      size_t used = 0;
      values.push_back(std::stod(token, &used));
      if (used != token.size()) throw std::invalid_argument(token);
    } catch (const std::exception&) {
      throw Error("'" + token + "' is not a number");
    }
  }
  const int count = static_cast<int>(values.size());
  if (count < min_numbers || count > 3) {
    throw Error(std::string(min_numbers == 3 ? "expected 3 numbers" : "expected 2 or 3 numbers") +
                ", got " + std::to_string(count));
  }
  return {values[0], values[1], count == 3 ? values[2] : 0.0};
}

}  // namespace areomap
