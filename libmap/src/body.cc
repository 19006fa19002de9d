#include "areomap/map/body.h"

#include <cctype>
#include <cmath>
#include <sstream>

#include "areomap/map/error.h"

namespace areomap {

Body Body::Mars2000() { return Body{"Mars2000", 3396190.0, 3376200.0}; }
Body Body::MarsSphere() { return Body{"MarsSphere", 3396190.0, 3396190.0}; }
Body Body::MolaSphere() { return Body{"MolaSphere", 3396000.0, 3396000.0}; }
Body Body::Sphere(double radius, std::string name) { return Body{std::move(name), radius, radius}; }

std::vector<std::string> Body::Names() { return {"mars2000", "mars-sphere", "mola-sphere"}; }

Body Body::FromName(std::string_view name) {
  std::string lower(name);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == "mars2000") return Mars2000();
  if (lower == "mars-sphere") return MarsSphere();
  if (lower == "mola-sphere") return MolaSphere();
  throw Error("unknown body '" + std::string(name) +
              "': expected one of mars2000, mars-sphere, mola-sphere");
}

double Body::InverseFlattening() const { return IsSphere() ? 0.0 : a / (a - b); }

double Body::RadiusAtPlanetocentricLatitude(double lat_c) const {
  const double bc = b * std::cos(lat_c);
  const double as = a * std::sin(lat_c);
  return a * b / std::sqrt(bc * bc + as * as);
}

void Body::Check() const {
  if (!(std::isfinite(a) && a > 0.0 && std::isfinite(b) && b > 0.0 && b <= a)) {
    std::ostringstream msg;
    msg << "body '" << name << "': radii a=" << a << " m, b=" << b
        << " m are invalid: expected finite 0 < b <= a";
    throw Error(msg.str());
  }
}

bool operator==(const Body& lhs, const Body& rhs) { return lhs.a == rhs.a && lhs.b == rhs.b; }

}  // namespace areomap
