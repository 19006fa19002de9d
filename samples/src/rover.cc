#include "areomap/samples/rover.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "shading.h"

namespace areomap {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Rasterizes one triangle of projected vertices (u, v, range) into the buffers.
void DrawTriangle(const Eigen::Vector3f& p0, const Eigen::Vector3f& p1, const Eigen::Vector3f& p2,
                  float i0, float i1, float i2, cv::Mat& range, cv::Mat& radiance) {
  const float area = (p1.x() - p0.x()) * (p2.y() - p0.y()) - (p2.x() - p0.x()) * (p1.y() - p0.y());
  if (std::abs(area) < 1e-12f) return;
  const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({p0.x(), p1.x(), p2.x()}))));
  const int x1 =
      std::min(range.cols - 1, static_cast<int>(std::floor(std::max({p0.x(), p1.x(), p2.x()}))));
  const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({p0.y(), p1.y(), p2.y()}))));
  const int y1 =
      std::min(range.rows - 1, static_cast<int>(std::floor(std::max({p0.y(), p1.y(), p2.y()}))));
  const float inverse_area = 1.0f / area;
  for (int y = y0; y <= y1; ++y) {
    float* range_row = range.ptr<float>(y);
    float* radiance_row = radiance.ptr<float>(y);
    for (int x = x0; x <= x1; ++x) {
      const float px = static_cast<float>(x), py = static_cast<float>(y);
      const float w0 =
          ((p1.x() - px) * (p2.y() - py) - (p2.x() - px) * (p1.y() - py)) * inverse_area;
      const float w1 =
          ((p2.x() - px) * (p0.y() - py) - (p0.x() - px) * (p2.y() - py)) * inverse_area;
      const float w2 = 1.0f - w0 - w1;
      if (w0 < 0.0f || w1 < 0.0f || w2 < 0.0f) continue;
      const float r = w0 * p0.z() + w1 * p1.z() + w2 * p2.z();
      if (r < range_row[x]) {
        range_row[x] = r;
        radiance_row[x] = w0 * i0 + w1 * i1 + w2 * i2;
      }
    }
  }
}

}  // namespace

StereoCameraOptions PancamOptions() {
  StereoCameraOptions o;
  o.name = "PANCAM";
  o.focal_length_mm = 43.0;
  o.baseline_m = 0.30;
  o.radial_distortion = Eigen::Vector3d::Zero();  // Pancam's distortion is negligible.
  return o;
}

double StereoCameraOptions::FocalLengthPx() const {
  if (field_of_view_deg > 0.0) return 0.5 * width / std::tan(RadFromDeg(field_of_view_deg) / 2.0);
  return focal_length_mm * 1e-3 / (pixel_pitch_um * 1e-6);
}

double StereoCameraOptions::FieldOfViewDeg() const {
  if (field_of_view_deg > 0.0) return field_of_view_deg;
  return DegFromRad(2.0 * std::atan(0.5 * width / FocalLengthPx()));
}

void StereoCameraOptions::Check() const {
  const std::string prefix = "StereoCameraOptions(" + name + ").";
  RequireOption(width >= 16 && height >= 16 && width <= 8192 && height <= 8192,
                prefix + "width/height", "16..8192 px");
  RequireOption(focal_length_mm > 0.0, prefix + "focal_length_mm", "> 0");
  RequireOption(pixel_pitch_um > 0.0, prefix + "pixel_pitch_um", "> 0");
  RequireOption(baseline_m > 0.0 && baseline_m < 5.0, prefix + "baseline_m", "0 < b < 5 m");
  RequireOption(field_of_view_deg >= 0.0 && field_of_view_deg < 180.0, prefix + "field_of_view_deg",
                "0 (from the focal length) or a field of view below 180 degrees");
}

void RenderOptions::Check() const {
  RequireOption(sun_elevation_deg > 0.0 && sun_elevation_deg < 90.0,
                "RenderOptions.sun_elevation_deg", "in (0, 90)");
  RequireOption(
      near_posting_m > 0.0 && mid_posting_m >= near_posting_m && far_posting_m >= mid_posting_m,
      "RenderOptions postings", "0 < near <= mid <= far");
  RequireOption(near_radius_m > 0.0 && mid_radius_m > near_radius_m, "RenderOptions radii",
                "0 < near < mid");
  RequireOption(bits >= 8 && bits <= 16, "RenderOptions.bits", "8..16");
}

std::array<CahvorModel, 2> StereoCameras(const StereoCameraOptions& o,
                                         const StereoPointing& pointing) {
  o.Check();
  const double f = o.FocalLengthPx();
  const double cx = (o.width - 1) / 2.0, cy = (o.height - 1) / 2.0;
  const double ca = std::cos(pointing.azimuth), sa = std::sin(pointing.azimuth);
  const double ce = std::cos(pointing.elevation), se = std::sin(pointing.elevation);
  const Eigen::Vector3d axis(ce * ca, ce * sa, -se);  // Rover frame: z down.
  const Eigen::Vector3d right(-sa, ca, 0.0);
  const Eigen::Vector3d down = axis.cross(right);
  std::array<CahvorModel, 2> cameras;
  for (int side = 0; side < 2; ++side) {
    CahvorModel& m = cameras[static_cast<size_t>(side)];
    m.c = o.mast_head_in_rover + (side == 0 ? -0.5 : 0.5) * o.baseline_m * right;
    m.a = axis;
    m.h = f * right + cx * axis;
    m.v = f * down + cy * axis;
    m.o = axis;
    m.r = o.radial_distortion;
  }
  return cameras;
}

std::vector<StereoPointing> Panorama(int pairs, double elevation) {
  std::vector<StereoPointing> out;
  for (int i = 0; i < pairs; ++i) {
    out.push_back({2.0 * std::numbers::pi * i / pairs, elevation});
  }
  return out;
}

SiteMesh::SiteMesh(const Scene& scene, const Eigen::Vector3d& site_in_enu,
                   const RenderOptions& options)
    : center_(site_in_enu), options_(options) {
  options.Check();
  // Coarse to fine squares centred on the site (the terrain function extends beyond the scene's
  // square, without craters or rocks there).
  const std::array<std::pair<double, double>, 3> rings = {
      std::pair{options.far_posting_m, options.far_radius_m},
      std::pair{options.mid_posting_m, options.mid_radius_m},
      std::pair{options.near_posting_m, options.near_radius_m}};
  const Eigen::Vector3d sun =
      internal::SunDirection(options.sun_azimuth_deg, options.sun_elevation_deg);
  for (size_t k = 0; k < rings.size(); ++k) {
    Level level;
    level.posting = rings[k].first;
    const double half = rings[k].second;
    level.size = static_cast<int>(std::floor(2.0 * half / level.posting)) + 1;
    level.origin = site_in_enu.head<2>() - Eigen::Vector2d::Constant(half);
    level.inner_half = k + 1 < rings.size() ? rings[k + 1].second : 0.0;
    const int n = level.size;
    level.points.resize(static_cast<size_t>(n) * n);
    std::vector<float> albedo(level.points.size());
    tbb::parallel_for(0, n, [&](int j) {
      for (int i = 0; i < n; ++i) {
        const double x = level.origin.x() + i * level.posting;
        const double y = level.origin.y() + j * level.posting;
        const size_t index = static_cast<size_t>(j) * n + i;
        level.points[index] = Eigen::Vector3d(x, y, scene.HeightAt(x, y)).cast<float>();
        albedo[index] = static_cast<float>(scene.AlbedoAt(x, y));
      }
    });
    // Cast shadows on this ring (north-up grid), or-ed with the coarser ring's.
    cv::Mat heights(n, n, CV_64F);
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        heights.at<double>(n - 1 - j, i) = level.points[static_cast<size_t>(j) * n + i].z();
      }
    }
    const cv::Mat shadow = internal::ShadowMask(heights, level.posting, sun);
    level.radiance.resize(level.points.size());
    tbb::parallel_for(0, n, [&](int j) {
      for (int i = 0; i < n; ++i) {
        const size_t index = static_cast<size_t>(j) * n + i;
        const auto z = [&](int ii, int jj) {
          return static_cast<double>(level
                                         .points[static_cast<size_t>(std::clamp(jj, 0, n - 1)) * n +
                                                 std::clamp(ii, 0, n - 1)]
                                         .z());
        };
        const Eigen::Vector3d normal(-(z(i + 1, j) - z(i - 1, j)) / (2.0 * level.posting),
                                     -(z(i, j + 1) - z(i, j - 1)) / (2.0 * level.posting), 1.0);
        const Eigen::Vector3d unit = normal.normalized();
        bool shadowed = shadow.at<uchar>(n - 1 - j, i) != 0;
        if (!shadowed && !levels_.empty()) {
          const Level& coarse = levels_.back();
          const Eigen::Vector2d rel =
              (level.points[index].head<2>().cast<double>() - coarse.origin) / coarse.posting;
          const int ci = std::clamp(static_cast<int>(std::lround(rel.x())), 0, coarse.size - 1);
          const int cj = std::clamp(static_cast<int>(std::lround(rel.y())), 0, coarse.size - 1);
          shadowed = coarse.radiance[static_cast<size_t>(cj) * coarse.size + ci] < 0.0f;
        }
        const double direct = shadowed ? 0.0 : std::max(0.0, unit.dot(sun));
        const double value = albedo[index] * (direct + options.ambient * unit.z());
        // A negative sign marks shadow for the finer rings; magnitudes are radiances.
        level.radiance[index] = static_cast<float>(shadowed ? -std::max(value, 1e-6) : value);
      }
    });
    levels_.push_back(std::move(level));
  }
}

SiteMesh::Image SiteMesh::Render(const CahvorModel& camera, int width, int height,
                                 uint32_t seed) const {
  cv::Mat range(height, width, CV_32F, cv::Scalar(std::numeric_limits<float>::infinity()));
  cv::Mat radiance(height, width, CV_32F, cv::Scalar(static_cast<float>(options_.sky_radiance)));
  const double margin = 64.0;
  for (const Level& level : levels_) {
    const int n = level.size;
    std::vector<Eigen::Vector3f> projected(level.points.size());
    tbb::parallel_for(0, n, [&](int j) {
      for (int i = 0; i < n; ++i) {
        const size_t index = static_cast<size_t>(j) * n + i;
        const Eigen::Vector3d p = level.points[index].cast<double>();
        const auto pixel = camera.Project(p);
        if (!pixel || pixel->x() < -margin || pixel->y() < -margin || pixel->x() > width + margin ||
            pixel->y() > height + margin) {
          projected[index] = Eigen::Vector3f(kNaNf, kNaNf, kNaNf);
        } else {
          projected[index] =
              Eigen::Vector3f(static_cast<float>(pixel->x()), static_cast<float>(pixel->y()),
                              static_cast<float>((p - camera.c).norm()));
        }
      }
    });
    const double inner = level.inner_half;
    for (int j = 0; j + 1 < n; ++j) {
      for (int i = 0; i + 1 < n; ++i) {
        if (inner > 0.0) {
          // Cells the finer ring covers entirely are drawn there.
          const Eigen::Vector2d lo = level.origin + Eigen::Vector2d(i, j) * level.posting;
          const Eigen::Vector2d hi = lo + Eigen::Vector2d::Constant(level.posting);
          const Eigen::Vector2d c = center_.head<2>();
          if ((lo - c).cwiseAbs().maxCoeff() < inner && (hi - c).cwiseAbs().maxCoeff() < inner) {
            continue;
          }
        }
        const size_t a = static_cast<size_t>(j) * n + i, b = a + 1, c = a + n, d = c + 1;
        const Eigen::Vector3f &pa = projected[a], &pb = projected[b], &pc = projected[c],
                              &pd = projected[d];
        if (std::isnan(pa.z()) || std::isnan(pb.z()) || std::isnan(pc.z()) || std::isnan(pd.z())) {
          continue;
        }
        const float ra = std::abs(level.radiance[a]), rb = std::abs(level.radiance[b]);
        const float rc = std::abs(level.radiance[c]), rd = std::abs(level.radiance[d]);
        DrawTriangle(pa, pb, pd, ra, rb, rd, range, radiance);
        DrawTriangle(pa, pd, pc, ra, rd, rc, range, radiance);
      }
    }
  }
  Image out;
  out.range = range;
  out.range.setTo(kNaNf, range == std::numeric_limits<float>::infinity());
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double gain = options_.full_well_dn / 0.5;
  const double max_dn = std::pow(2.0, options_.bits) - 1.0;
  out.dn = cv::Mat(height, width, CV_16U);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double signal = radiance.at<float>(y, x) * gain;
      const double noisy =
          signal + gauss(rng) * std::sqrt(std::max(signal, 0.0) / 8.0 +
                                          options_.read_noise_dn * options_.read_noise_dn);
      out.dn.at<uint16_t>(y, x) = static_cast<uint16_t>(std::clamp(std::round(noisy), 0.0, max_dn));
    }
  }
  return out;
}

}  // namespace areomap
