// Rock catalogues and matches as CSV and JSON files.
#include "areomap/registration/rock_output.h"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "areomap/map/atomic_file.h"

namespace areomap {

namespace {

std::string Number(double value, const char* format = "%.4f") {
  if (!std::isfinite(value)) return "";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

nlohmann::json Vector3Json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json ModelJson(const RockModelFit& fit) {
  const RockModelParameters& p = fit.parameters;
  nlohmann::json sigma = nlohmann::json::array();
  for (double s : fit.sigma) sigma.push_back(s);
  return {{"shape", ToString(p.shape)},
          {"converged", fit.converged},
          {"complex", fit.complex_model},
          {"points", fit.point_count},
          {"rms_m", fit.rms_m},
          {"height_m", p.height},
          {"a_m", p.a},
          {"b_m", p.b},
          {"phi_rad", p.phi},
          {"alpha_rad", p.alpha},
          {"beta_rad", p.beta},
          {"center_m", {p.center_x, p.center_y}},
          {"volume_m3", p.Volume()},
          {"surface_area_m2", p.SurfaceAreaExact()},
          {"surface_area_approx_m2", p.SurfaceAreaApprox()},
          {"sigma", sigma},
          {"message", fit.message}};
}

}  // namespace

nlohmann::json RockToJson(const ExtractedRock& rock) {
  nlohmann::json covariance = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) {
    covariance.push_back(
        {rock.peak_covariance(r, 0), rock.peak_covariance(r, 1), rock.peak_covariance(r, 2)});
  }
  nlohmann::json models = nlohmann::json::array();
  for (const RockModelFit& fit : rock.models) models.push_back(ModelJson(fit));
  return {{"id", rock.id},
          {"peak_m", Vector3Json(rock.peak)},
          {"peak_covariance_m2", covariance},
          {"range_m", rock.range_m},
          {"height_m", rock.height_m},
          {"plane_normal", Vector3Json(rock.plane_normal)},
          {"peak_foot_m", Vector3Json(rock.peak_foot)},
          {"background_points", rock.background_points},
          {"ground_sigma_m", rock.ground_sigma_m},
          {"surface_points", rock.surface_indices.size()},
          {"surface_radius_m", rock.surface_radius_m},
          {"modeled", rock.modeled()},
          {"models", models}};
}

nlohmann::json RockExtractionSummaryToJson(const RockExtractionSummary& s) {
  return {{"points", s.points},
          {"peak_candidates", s.peak_candidates},
          {"beyond_range", s.beyond_range},
          {"too_low", s.too_low},
          {"merged", s.merged},
          {"rocks", s.rocks},
          {"modeled", s.modeled}};
}

void WriteRocksCsv(const std::filesystem::path& path, const std::vector<ExtractedRock>& rocks) {
  std::ostringstream out;
  out << "id,x_m,y_m,z_m,sigma_x_m,sigma_y_m,sigma_z_m,range_m,height_m,normal_x,normal_y,"
         "normal_z,surface_points,ground_sigma_m,model,model_height_m,model_a_m,model_b_m,"
         "model_rms_m,volume_m3,surface_area_m2\n";
  for (const ExtractedRock& r : rocks) {
    out << r.id << ',' << Number(r.peak.x()) << ',' << Number(r.peak.y()) << ','
        << Number(r.peak.z()) << ',' << Number(std::sqrt(r.peak_covariance(0, 0))) << ','
        << Number(std::sqrt(r.peak_covariance(1, 1))) << ','
        << Number(std::sqrt(r.peak_covariance(2, 2))) << ',' << Number(r.range_m, "%.3f") << ','
        << Number(r.height_m) << ',' << Number(r.plane_normal.x(), "%.5f") << ','
        << Number(r.plane_normal.y(), "%.5f") << ',' << Number(r.plane_normal.z(), "%.5f") << ','
        << r.surface_indices.size() << ',' << Number(r.ground_sigma_m);
    if (const RockModelFit* m = r.best_model()) {
      const RockModelParameters& p = m->parameters;
      out << ',' << ToString(p.shape) << ',' << Number(p.height) << ',' << Number(p.a) << ','
          << Number(p.b) << ',' << Number(m->rms_m, "%.5f") << ',' << Number(p.Volume(), "%.6f")
          << ',' << Number(p.SurfaceAreaExact(), "%.5f");
    } else {
      out << ",,,,,,,";
    }
    out << '\n';
  }
  WriteFileAtomically(path, out.str());
}

void WriteRocksJson(const std::filesystem::path& path, const std::vector<ExtractedRock>& rocks) {
  nlohmann::json list = nlohmann::json::array();
  for (const ExtractedRock& r : rocks) list.push_back(RockToJson(r));
  WriteFileAtomically(
      path,
      nlohmann::json{{"frame", "site (x north, y east, z down) [m]"}, {"rocks", list}}.dump(2) +
          "\n");
}

void WriteRockMatchesCsv(const std::filesystem::path& path, const SiteRocks& a, const SiteRocks& b,
                         const SitePairMatch& match) {
  std::ostringstream out;
  out << "rock_a,rock_b,xa_m,ya_m,za_m,xb_m,yb_m,zb_m,model_cost,pattern_votes,normal_angle_deg,"
         "distance_ratio\n";
  for (const RockMatch& m : match.matches) {
    const ExtractedRock& p = a.rocks.at(static_cast<size_t>(m.rock_a));
    const ExtractedRock& q = b.rocks.at(static_cast<size_t>(m.rock_b));
    out << p.id << ',' << q.id << ',' << Number(p.peak.x()) << ',' << Number(p.peak.y()) << ','
        << Number(p.peak.z()) << ',' << Number(q.peak.x()) << ',' << Number(q.peak.y()) << ','
        << Number(q.peak.z()) << ',' << Number(m.model_cost) << ',' << m.pattern_count << ','
        << Number(m.normal_angle_deg, "%.2f") << ',' << Number(m.distance_ratio, "%.3f") << '\n';
  }
  WriteFileAtomically(path, out.str());
}

}  // namespace areomap
