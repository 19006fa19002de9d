#include "areomap/crater/learned_detector.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <utility>

#include <tbb/parallel_for.h>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/numbers.h"
#include "areomap/map/report_progress.h"
#include "detect_in_core.h"
#include "raster_levels.h"

namespace areomap {
namespace internal {
extern const unsigned char kCraterModelOnnx[];
extern const std::size_t kCraterModelOnnx_size;
}  // namespace internal

namespace {

// The network's geometry; scripts/crater_model/crater_net.py holds the same numbers.
constexpr int kStride = 2;               // output cell [input px]
constexpr int kPadMultiple = 8;          // input sizes must be multiples of this
constexpr double kDiameterUnitPx = 8.0;  // the size head predicts log(D / 8 px)
constexpr int kNormalizeBoxPx = 31;      // local mean / std window
constexpr float kNormalizeClip = 4.0f;
constexpr double kBandLowPx = 12.0;  // a level's own band: 12-24 px of its own (level 0: < 24)
constexpr double kBandHighPx = 24.0;
// A level above 0 also reports craters down to its band's lower edge / this factor, which the
// next finer level reports too; duplicates of two levels are then suppressed. Without the overlap
// a crater whose diameter the finer level put just over its band and the coarser level just under
// its own was reported by neither. The bands are not widened upwards: a finer level does not see
// a larger crater whole, and takes its floor and walls for craters.
constexpr double kBandOverlap = 1.25;
constexpr int kMinLevelSizePx = 48;  // no level smaller than this
// The network is not asked for craters wider than this [px of a level] (train.py
// --max-net-diameter): a rim wider at the coarsest level lies beyond its reach.
constexpr double kNetworkMaxDiameterPx = 48.0;
// Margin of a level tile [px of the level]: the normalisation's half box (15) plus the
// network's half receptive field (~37), rounded up to a multiple of 8 so that tiles keep the
// stride-8 grid of the whole level and give the same outputs.
constexpr int kTileMarginPx = 64;
// Errors of the network's circles against the held-out CTX labels (docs/crater-model.md), as
// fractions of the diameter: 1-sigma of the centre per axis and of the diameter.
constexpr double kCircleCenterSigma = 0.053;
constexpr double kCircleDiameterSigma = 0.108;
// A circle without a rim fit meets the diameter limits when it does so within this many of its
// sigmas: the network's diameters regress towards the middle of its range, so a circle measured
// just under the lower limit is more often than not a crater at or over it (docs/crater-model.md:
// true / predicted 1.10-1.13 for predictions of 6-10 px on the validation images).
constexpr double kLimitSigmas = 2.0;
constexpr double kCircleLimitTolerance = kLimitSigmas * kCircleDiameterSigma;
// A rim fit replaces the circle only where it agrees with it: centres within a quarter of the
// diameter, diameters within 25 %.
constexpr double kRefineMaxShift = 0.25;
constexpr double kRefineMaxRatio = 1.25;

// Reads `rect` (pixels of pyramid level `level`) as CV_32F, NaN = nodata.
using LevelReader = std::function<cv::Mat(int level, const cv::Rect& rect)>;

struct Pyramid {
  int width = 0, height = 0;  // level 0
  int levels = 0;
  cv::Size LevelSize(int level) const { return {width >> level, height >> level}; }
};

Pyramid PyramidOf(int width, int height) {
  Pyramid p{width, height, 0};
  while (p.levels == 0 || std::min(width >> p.levels, height >> p.levels) >= kMinLevelSizePx) {
    ++p.levels;
  }
  return p;
}

// The rim diameters [full-resolution px] that `level` reports, [lo, hi): level 0 everything under
// 24 px, a level above it 9.6-24 px of its own (12-24 px widened down by kBandOverlap), the last
// level everything from 9.6 px of its own.
struct DiameterBand {
  double lo = 0.0, hi = 0.0;
};

DiameterBand BandOf(const Pyramid& pyramid, int level) {
  const double f = std::ldexp(1.0, level);
  const bool last = level + 1 == pyramid.levels;
  return {level == 0 ? 0.0 : kBandLowPx / kBandOverlap * f,
          last ? std::numeric_limits<double>::infinity() : kBandHighPx * f};
}

int TileCount(const cv::Size& size, int tile) {
  return ((size.width + tile - 1) / tile) * ((size.height + tile - 1) / tile);
}

// One detection of the network, in full-resolution pixels.
struct Peak {
  double x = 0.0, y = 0.0, diameter = 0.0, score = 0.0;
  int level = 0;
};

// Peaks of the heat map (3x3 local maxima >= min_score) whose centre lies in `core` (pixels of
// the tile), in tile pixels of the level.
std::vector<Peak> Decode(const CraterNetwork::Output& out, double min_score, const cv::Rect& core) {
  cv::Mat dilated;
  cv::dilate(out.heat, dilated, cv::Mat::ones(3, 3, CV_8U));
  std::vector<Peak> peaks;
  for (int i = 0; i < out.heat.rows; ++i) {
    const float* h = out.heat.ptr<float>(i);
    const float* m = dilated.ptr<float>(i);
    for (int j = 0; j < out.heat.cols; ++j) {
      if (!(h[j] >= min_score) || h[j] < m[j]) continue;
      Peak p;
      p.x = (j + 0.5 + static_cast<double>(out.dx.at<float>(i, j))) * kStride;
      p.y = (i + 0.5 + static_cast<double>(out.dy.at<float>(i, j))) * kStride;
      p.diameter = std::exp(out.log_diameter.at<float>(i, j)) * kDiameterUnitPx;
      p.score = h[j];
      if (p.x >= core.x && p.x < core.x + core.width && p.y >= core.y &&
          p.y < core.y + core.height) {
        peaks.push_back(p);
      }
    }
  }
  return peaks;
}

// Share of nodata pixels of `tile` inside the circle (tile pixels).
double NodataShare(const cv::Mat& nodata, double x, double y, double radius) {
  if (nodata.empty()) return 0.0;
  const int c0 = std::max(0, static_cast<int>(x - radius)),
            r0 = std::max(0, static_cast<int>(y - radius));
  const int c1 = std::min(nodata.cols, static_cast<int>(x + radius) + 1);
  const int r1 = std::min(nodata.rows, static_cast<int>(y + radius) + 1);
  int inside = 0, missing = 0;
  for (int r = r0; r < r1; ++r) {
    const uchar* row = nodata.ptr<uchar>(r);
    for (int c = c0; c < c1; ++c) {
      const double dx = c + 0.5 - x, dy = r + 0.5 - y;
      if (dx * dx + dy * dy > radius * radius) continue;
      ++inside;
      missing += row[c] ? 1 : 0;
    }
  }
  return inside > 0 ? static_cast<double>(missing) / inside : 1.0;
}

// NormalizeForCraterNetwork with `image`'s NaN mask already made: NanMask(image), or empty where
// `image` holds no NaN.
cv::Mat NormalizeWithNodata(const cv::Mat& image, const cv::Mat& nodata) {
  cv::Mat x;
  image.convertTo(x, CV_32F);
  const bool has_nodata = !nodata.empty();
  if (has_nodata) {
    // Nodata takes the mean of the valid pixels, so that it adds no edge.
    const cv::Scalar mean = cv::mean(x, ~nodata);
    x.setTo(mean[0], nodata);
  }
  const cv::Size box(kNormalizeBoxPx, kNormalizeBoxPx);
  cv::Mat mean, square_mean;
  cv::boxFilter(x, mean, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_REFLECT_101);
  cv::boxFilter(x.mul(x), square_mean, CV_32F, box, cv::Point(-1, -1), true,
                cv::BORDER_REFLECT_101);
  cv::Mat out(x.size(), CV_32F);
  for (int r = 0; r < x.rows; ++r) {
    const float* v = x.ptr<float>(r);
    const float* m = mean.ptr<float>(r);
    const float* s = square_mean.ptr<float>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < x.cols; ++c) {
      const float sd =
          std::sqrt(std::max(s[c] - m[c] * m[c], 0.0f)) + 1e-3f * std::abs(m[c]) + 1e-12f;
      o[c] = std::clamp((v[c] - m[c]) / sd, -kNormalizeClip, kNormalizeClip);
    }
  }
  if (has_nodata) out.setTo(0.0f, nodata);
  return out;
}

// The network's peaks >= `min_score` on one pyramid level, tile by tile, in full-resolution
// pixels.
std::vector<Peak> DetectOnLevel(CraterNetwork& network, const LevelReader& read, int level,
                                const Pyramid& pyramid, const LearnedDetectorOptions& learned,
                                double min_score, const std::function<void()>& tile_done) {
  const cv::Size size = pyramid.LevelSize(level);
  const DiameterBand band = BandOf(pyramid, level);
  const int tile = learned.tile_size;
  std::vector<Peak> peaks;
  for (int core_r0 = 0; core_r0 < size.height; core_r0 += tile) {
    for (int core_c0 = 0; core_c0 < size.width; core_c0 += tile) {
      const cv::Rect core_rect(core_c0, core_r0, std::min(tile, size.width - core_c0),
                               std::min(tile, size.height - core_r0));
      const int c0 = std::max(0, core_c0 - kTileMarginPx);
      const int r0 = std::max(0, core_r0 - kTileMarginPx);
      const int c1 = std::min(size.width, core_rect.br().x + kTileMarginPx);
      const int r1 = std::min(size.height, core_rect.br().y + kTileMarginPx);
      const cv::Mat raw = read(level, cv::Rect(c0, r0, c1 - c0, r1 - r0));
      cv::Mat nodata = NanMask(raw);
      const int nodata_count = cv::countNonZero(nodata);
      if (nodata_count == raw.rows * raw.cols) {
        tile_done();
        continue;
      }
      if (nodata_count == 0) nodata.release();
      cv::Mat input = NormalizeWithNodata(raw, nodata);
      const int pad_r = (kPadMultiple - input.rows % kPadMultiple) % kPadMultiple;
      const int pad_c = (kPadMultiple - input.cols % kPadMultiple) % kPadMultiple;
      if (pad_r || pad_c) {
        // A 1-pixel side cannot be reflected; replicate it instead.
        const int border =
            std::min(input.rows, input.cols) > 1 ? cv::BORDER_REFLECT_101 : cv::BORDER_REPLICATE;
        cv::copyMakeBorder(input, input, 0, pad_r, 0, pad_c, border);
      }
      const CraterNetwork::Output out = network.Forward(input);
      const cv::Rect core_in_tile(core_rect.x - c0, core_rect.y - r0, core_rect.width,
                                  core_rect.height);
      for (Peak p : Decode(out, min_score, core_in_tile)) {
        if (NodataShare(nodata, p.x, p.y, 0.5 * p.diameter) > 0.25) continue;
        const double f = std::ldexp(1.0, level);
        p.x = (p.x + c0) * f;
        p.y = (p.y + r0) * f;
        p.diameter *= f;
        if (p.diameter < band.lo || p.diameter >= band.hi) continue;
        p.level = level;
        peaks.push_back(p);
      }
      tile_done();
    }
  }
  return peaks;
}

CraterDetection CircleDetection(const Peak& p, int width, int height) {
  CraterDetection d;
  d.ellipse.center = Eigen::Vector2d(p.x, p.y);
  d.ellipse.semi_major = d.ellipse.semi_minor = 0.5 * p.diameter;
  d.ellipse.angle = 0.0;
  d.center_x_sigma = d.center_y_sigma = kCircleCenterSigma * p.diameter;
  d.semi_major_sigma = d.semi_minor_sigma = 0.5 * kCircleDiameterSigma * p.diameter;
  d.angle_sigma = kNaN;
  d.rms_residual = d.efs = d.coverage = d.signature = d.shading_correlation = kNaN;
  d.edge_contrast = kNaN;
  d.num_edge_points = 0;
  d.confidence = p.score;
  d.model_score = p.score;
  d.pyramid_level = p.level;
  d.rim_fitted = false;
  d.edge_detected = false;
  const double r = 0.5 * p.diameter;
  d.partial = p.x - r < 0.0 || p.y - r < 0.0 || p.x + r > width || p.y + r > height;
  return d;
}

// The rim fitted as an ellipse on a window around the circle, read at the level where the crater
// spans 48-96 px (or full resolution); nullopt when the rim has too few edges or the fit strays
// from the network's circle.
std::optional<CraterDetection> FitRim(const LevelReader& read, const Pyramid& pyramid,
                                      const CraterDetection& circle,
                                      const CraterDetectorOptions& options) {
  const int level = std::max(0, circle.pyramid_level - 2);
  const double f = std::ldexp(1.0, level);
  const cv::Size size = pyramid.LevelSize(level);
  const double x = circle.ellipse.center.x() / f, y = circle.ellipse.center.y() / f;
  const double r = circle.ellipse.semi_major / f;
  const double reach = 1.5 * r + 6.0;
  const int c0 = std::max(0, static_cast<int>(x - reach)),
            r0 = std::max(0, static_cast<int>(y - reach));
  const int c1 = std::min(size.width, static_cast<int>(x + reach) + 1);
  const int r1 = std::min(size.height, static_cast<int>(y + reach) + 1);
  if (c1 - c0 < 8 || r1 - r0 < 8) return std::nullopt;
  const cv::Mat window = read(level, cv::Rect(c0, r0, c1 - c0, r1 - r0));
  Ellipse initial = circle.ellipse;
  initial.center = Eigen::Vector2d(x - c0, y - r0);
  initial.semi_major = initial.semi_minor = r;
  CraterDetectorOptions fit_options = options;
  fit_options.min_diameter_px = CraterDetectorOptions::kSmallestDiameterPx;
  fit_options.max_diameter_px = 0.0;
  std::optional<CraterDetection> fit =
      RefineCrater(window, RimSource::kImage, initial, fit_options);
  if (!fit) return std::nullopt;
  const double shift = (fit->ellipse.center - initial.center).norm();
  const double ratio = fit->Diameter() / (2.0 * r);
  if (shift > kRefineMaxShift * 2.0 * r || ratio > kRefineMaxRatio ||
      ratio < 1.0 / kRefineMaxRatio) {
    return std::nullopt;
  }
  CraterDetection d = internal::ShiftedDetection(*fit, c0 * f, r0 * f, f);
  d.confidence = circle.confidence;
  d.model_score = circle.model_score;
  d.pyramid_level = circle.pyramid_level;
  d.rim_fitted = true;
  d.edge_detected = false;
  d.partial = d.partial || circle.partial;
  return d;
}

// The diameters [full-resolution px] that meet options' limits within `tolerance` (a fraction of
// the diameter): [min / (1 + tolerance), max / (1 - tolerance)], never under
// CraterDetectorOptions::kSmallestDiameterPx; tolerance 0 gives the limits themselves.
DiameterBand DiameterLimits(const CraterDetectorOptions& options, double tolerance) {
  return {std::max(CraterDetectorOptions::kSmallestDiameterPx,
                   options.min_diameter_px / (1.0 + tolerance)),
          options.max_diameter_px > 0.0 ? options.max_diameter_px / (1.0 - tolerance)
                                        : std::numeric_limits<double>::infinity()};
}

// Fitted rims within the diameter limits, circles within kCircleLimitTolerance of them; in their
// order.
std::vector<CraterDetection> KeepWithinLimitsOrUncertainty(std::vector<CraterDetection> detections,
                                                           const CraterDetectorOptions& options) {
  const DiameterBand rims = DiameterLimits(options, 0.0);
  const DiameterBand circles = DiameterLimits(options, kCircleLimitTolerance);
  std::erase_if(detections, [&](const CraterDetection& d) {
    const DiameterBand& band = d.rim_fitted ? rims : circles;
    return d.Diameter() < band.lo || d.Diameter() > band.hi;
  });
  return detections;
}

// The learned detector's craters and, with `with_support`, the combined detector's support.
internal::LearnedFinds DetectLearned(const LevelReader& read, int width, int height,
                                     const CraterDetectorOptions& options,
                                     const LearnedDetectorOptions& learned, bool with_support,
                                     const ProgressCallback& progress) {
  options.Check();
  learned.Check();
  CraterNetwork network(learned.model_path);
  internal::LearnedFinds finds;
  if (width <= 0 || height <= 0) return finds;
  const Pyramid pyramid = PyramidOf(width, height);
  const double support_score =
      with_support ? std::min(learned.edge_support_score, learned.min_score) : 0.0;
  if (support_score > 0.0) {
    finds.support.reach_px = kNetworkMaxDiameterPx * std::ldexp(1.0, pyramid.levels - 1);
  }
  // Levels whose band cannot hold a crater of the asked diameters are not searched.
  const DiameterBand limits = DiameterLimits(options, kCircleLimitTolerance);
  const double lo = limits.lo, hi = limits.hi;
  const auto searched = [&](int level) {
    const DiameterBand band = BandOf(pyramid, level);
    return band.hi >= lo && band.lo <= hi;
  };
  int tiles = 0;
  for (int l = 0; l < pyramid.levels; ++l) {
    if (searched(l)) tiles += TileCount(pyramid.LevelSize(l), learned.tile_size);
  }
  const double detect_share = learned.refine_rims ? 0.7 : 1.0;
  int done = 0;
  const auto tile_done = [&] {
    ReportProgress(progress, detect_share * (++done) / std::max(1, tiles), "craters: network");
  };
  const double decode_score = support_score > 0.0 ? support_score : learned.min_score;
  std::vector<CraterDetection> circles;
  for (int l = 0; l < pyramid.levels; ++l) {
    if (!searched(l)) continue;
    for (const Peak& p :
         DetectOnLevel(network, read, l, pyramid, learned, decode_score, tile_done)) {
      if (support_score > 0.0) {
        finds.support.circles.push_back({Eigen::Vector2d(p.x, p.y), p.diameter});
      }
      if (p.score >= learned.min_score && p.diameter >= lo && p.diameter <= hi)
        circles.push_back(CircleDetection(p, width, height));
    }
  }
  circles = SuppressDuplicateCraters(std::move(circles));
  if (learned.refine_rims) {
    std::vector<CraterDetection> refined = circles;
    tbb::parallel_for(size_t{0}, circles.size(), [&](size_t i) {
      if (auto fit = FitRim(read, pyramid, circles[i], options)) refined[i] = *fit;
    });
    circles = SuppressDuplicateCraters(std::move(refined));
  }
  ReportProgress(progress, 1.0, "craters: done");
  finds.craters = KeepWithinLimitsOrUncertainty(std::move(circles), options);
  return finds;
}

}  // namespace

std::string ToString(CraterMethod method) {
  switch (method) {
    case CraterMethod::kCombined:
      return "combined";
    case CraterMethod::kLearned:
      return "learned";
    case CraterMethod::kEdges:
      break;
  }
  return "edges";
}

CraterMethod CraterMethodFromString(const std::string& name) {
  if (name == "combined") return CraterMethod::kCombined;
  if (name == "learned") return CraterMethod::kLearned;
  if (name == "edges") return CraterMethod::kEdges;
  throw Error("crater method: '" + name + "' is not one of combined, learned, edges");
}

void LearnedDetectorOptions::Check() const {
  RequireOption(std::isfinite(min_score) && min_score > 0.0 && min_score < 1.0,
                "LearnedDetectorOptions.min_score", "in (0, 1)");
  RequireOption(edge_support_score >= 0.0 && edge_support_score < 1.0,
                "LearnedDetectorOptions.edge_support_score", "in [0, 1)");
  RequireOption(tile_size >= 64, "LearnedDetectorOptions.tile_size", ">= 64 px");
}

struct CraterNetwork::Impl {
  cv::dnn::Net net;
  std::string source;
};

CraterNetwork::CraterNetwork(const std::string& model_path) : impl_(std::make_unique<Impl>()) {
  impl_->source = model_path.empty() ? std::string("built-in") : model_path;
  const std::string what = model_path.empty() ? "the built-in crater model" : model_path;
  if (!model_path.empty() && !std::filesystem::is_regular_file(model_path)) {
    throw Error(model_path + ": crater model file not found (expected an ONNX file)");
  }
  try {
    impl_->net = model_path.empty() ? cv::dnn::readNetFromONNX(
                                          reinterpret_cast<const char*>(internal::kCraterModelOnnx),
                                          internal::kCraterModelOnnx_size)
                                    : cv::dnn::readNetFromONNX(model_path);
  } catch (const cv::Exception& e) {
    throw Error(what + ": not a crater model OpenCV dnn can read (expected ONNX): " + e.msg);
  }
  if (impl_->net.empty()) throw Error(what + ": the ONNX file holds no network");
  impl_->net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  impl_->net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  // A model of another shape fails here, not inside a tile.
  try {
    const Output probe = Forward(cv::Mat::zeros(16, 16, CV_32F));
    if (probe.heat.rows != 8 || probe.heat.cols != 8) throw Error("");
  } catch (const std::exception&) {
    throw Error(what +
                ": not a crater model of the expected shape (1 x 1 x H x W image in, "
                "1 x 4 x H/2 x W/2 out: heat map, offsets, log diameter)");
  }
}

CraterNetwork::~CraterNetwork() = default;
CraterNetwork::CraterNetwork(CraterNetwork&&) noexcept = default;
CraterNetwork& CraterNetwork::operator=(CraterNetwork&&) noexcept = default;

const std::string& CraterNetwork::source() const { return impl_->source; }

CraterNetwork::Output CraterNetwork::Forward(const cv::Mat& normalized) {
  CV_Assert(normalized.type() == CV_32F && normalized.rows % kPadMultiple == 0 &&
            normalized.cols % kPadMultiple == 0);
  const int sizes[] = {1, 1, normalized.rows, normalized.cols};
  const cv::Mat blob(4, sizes, CV_32F, const_cast<float*>(normalized.ptr<float>()));
  impl_->net.setInput(blob);
  cv::Mat out;
  try {
    out = impl_->net.forward();
  } catch (const cv::Exception& e) {
    throw Error(impl_->source + ": the crater model failed to run: " + e.msg);
  }
  if (out.dims != 4 || out.size[0] != 1 || out.size[1] != 4 || out.size[2] * 2 != normalized.rows ||
      out.size[3] * 2 != normalized.cols) {
    throw Error(impl_->source + ": the crater model's output is not 1 x 4 x H/2 x W/2");
  }
  const int rows = out.size[2], cols = out.size[3];
  auto plane = [&](int k) { return cv::Mat(rows, cols, CV_32F, out.ptr<float>(0, k)).clone(); };
  return {plane(0), plane(1), plane(2), plane(3)};
}

cv::Mat NormalizeForCraterNetwork(const cv::Mat& image) {
  cv::Mat nodata = NanMask(image);
  if (cv::countNonZero(nodata) == 0) nodata.release();
  return NormalizeWithNodata(image, nodata);
}

namespace internal {

LearnedFinds DetectCratersLearnedOn(const RasterLevels& levels,
                                    const CraterDetectorOptions& options,
                                    const LearnedDetectorOptions& learned, bool with_support,
                                    const ProgressCallback& progress) {
  const LevelReader read = [&levels](int level, const cv::Rect& rect) {
    return levels.Read(level, rect);
  };
  return DetectLearned(read, levels.width(), levels.height(), options, learned, with_support,
                       progress);
}

LearnedFinds DetectCratersLearnedInImage(const cv::Mat& image, const CraterDetectorOptions& options,
                                         const LearnedDetectorOptions& learned, bool with_support,
                                         const ProgressCallback& progress) {
  if (image.channels() != 1) throw Error("crater detection: expected a single-band raster");
  // The pyramid of 2 x 2 box averages (NaN where any pixel of a block is).
  std::vector<cv::Mat> levels(1);
  image.convertTo(levels[0], CV_32F);
  const Pyramid pyramid = PyramidOf(image.cols, image.rows);
  for (int l = 1; l < pyramid.levels; ++l) {
    const cv::Mat& prev = levels.back();
    const cv::Size s = pyramid.LevelSize(l);
    cv::Mat next;
    cv::resize(prev(cv::Rect(0, 0, s.width * 2, s.height * 2)), next, s, 0, 0, cv::INTER_AREA);
    levels.push_back(next);
  }
  const LevelReader read = [&levels](int level, const cv::Rect& rect) {
    return levels[static_cast<size_t>(level)](rect).clone();
  };
  return DetectLearned(read, image.cols, image.rows, options, learned, with_support, progress);
}

}  // namespace internal

// On a raster larger than GDAL's block cache holds, the raster is decoded once into level files
// (raster_levels.h), not once per level and again for the network and the rim fits.
std::vector<CraterDetection> DetectCratersLearned(const RasterDataset& dataset,
                                                  const CraterDetectorOptions& options,
                                                  const LearnedDetectorOptions& learned,
                                                  const ProgressCallback& progress) {
  return internal::DetectCratersLearnedOn(internal::RasterLevels(dataset, /*decode_once=*/true),
                                          options, learned, /*with_support=*/false, progress)
      .craters;
}

std::vector<CraterDetection> DetectCratersLearned(const cv::Mat& image,
                                                  const CraterDetectorOptions& options,
                                                  const LearnedDetectorOptions& learned,
                                                  const ProgressCallback& progress) {
  return internal::DetectCratersLearnedInImage(image, options, learned, /*with_support=*/false,
                                               progress)
      .craters;
}

}  // namespace areomap
