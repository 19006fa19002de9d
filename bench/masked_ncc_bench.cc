// Masked NCC benchmark: the FFT implementation against the naive direct sum (same results,
// see tests/registration) and against OpenCV's cv::matchTemplate with a template mask, all in
// this process on the same inputs. OpenCV's baseline only masks the template and only scores
// shifts where the template lies wholly inside the image, so it does less work than the
// masked NCC (which also masks the fixed image and covers every partial overlap).
//
// Run: build/release/bench/areomap_bench [Google Benchmark flags]; a table of ratios follows
// the usual Google Benchmark output.
#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/registration/masked_ncc.h"

namespace areomap {
namespace {

// A rover-orthophoto-like template cut from an orbital-like texture: 30% of the template
// masked (blobs), a few holes in the fixed image's mask.
struct Scene {
  cv::Mat fixed;
  cv::Mat fixed_mask;
  cv::Mat moving;
  cv::Mat moving_mask;
  int true_x = 0;
  int true_y = 0;
};

cv::Mat Texture(int size, double sigma, cv::RNG& rng) {
  cv::Mat image(size, size, CV_32F);
  rng.fill(image, cv::RNG::UNIFORM, 0.0, 1000.0);
  cv::GaussianBlur(image, image, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  return image;
}

const Scene& GetScene(int template_size, int image_size) {
  static std::map<std::pair<int, int>, Scene> cache;
  auto [it, inserted] = cache.try_emplace({template_size, image_size});
  Scene& scene = it->second;
  if (!inserted) return scene;
  cv::RNG rng(12345);
  scene.fixed = Texture(image_size, 1.5, rng);
  scene.true_x = image_size / 3;
  scene.true_y = image_size / 2;
  scene.moving =
      scene.fixed(cv::Rect(scene.true_x, scene.true_y, template_size, template_size)).clone();
  const cv::Mat field = Texture(template_size, 4.0, rng);
  cv::Mat sorted = field.reshape(1, 1).clone();
  cv::sort(sorted, sorted, cv::SORT_ASCENDING);
  scene.moving_mask = field >= sorted.at<float>(0, static_cast<int>(0.3 * sorted.cols));
  scene.fixed_mask = cv::Mat(image_size, image_size, CV_8U, cv::Scalar(255));
  for (int k = 0; k < 10; ++k) {
    const int x = rng.uniform(0, image_size - 16);
    const int y = rng.uniform(0, image_size - 16);
    scene.fixed_mask(cv::Rect(x, y, 16, 16)).setTo(0);
  }
  return scene;
}

MaskedNccOptions WindowOptions(const Scene& scene, int radius, NccMethod method = NccMethod::kFft) {
  MaskedNccOptions options;
  options.method = method;
  options.search_window = ShiftWindow::Around(scene.true_x + 2, scene.true_y - 1, radius);
  return options;
}

void SetCounters(benchmark::State& state, const cv::Mat& surface) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) *
                          static_cast<int64_t>(surface.total()));
  state.counters["shifts"] = static_cast<double>(surface.total());
}

// Arguments: template size, image size [px]; window radius [px] for the windowed variants.
void BM_MaskedNccFft(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  MaskedNccOptions options;
  options.method = NccMethod::kFft;
  MaskedNccSurface surface;
  for (auto _ : state) {
    surface = MaskedNcc(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask, options);
    benchmark::DoNotOptimize(surface.ncc.data);
  }
  SetCounters(state, surface.ncc);
}

// The shifts cv::matchTemplate scores (template wholly inside the image), fixed image without
// holes: the same work as the OpenCV baseline; transforms in double or single precision.
template <FftPrecision kPrecision>
void BM_MaskedNccFftInside(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  MaskedNccOptions options;
  options.method = NccMethod::kFft;
  options.fft_precision = kPrecision;
  options.search_window =
      ShiftWindow{0, scene.fixed.cols - scene.moving.cols, 0, scene.fixed.rows - scene.moving.rows};
  MaskedNccSurface surface;
  for (auto _ : state) {
    surface = MaskedNcc(scene.fixed, cv::Mat(), scene.moving, scene.moving_mask, options);
    benchmark::DoNotOptimize(surface.ncc.data);
  }
  SetCounters(state, surface.ncc);
}

void BM_MaskedNccNaive(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  MaskedNccSurface surface;
  for (auto _ : state) {
    surface = MaskedNccNaive(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask);
    benchmark::DoNotOptimize(surface.ncc.data);
  }
  SetCounters(state, surface.ncc);
}

void BM_MaskedNccFftWindow(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const MaskedNccOptions options = WindowOptions(scene, static_cast<int>(state.range(2)));
  MaskedNccSurface surface;
  for (auto _ : state) {
    surface = MaskedNcc(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask, options);
    benchmark::DoNotOptimize(surface.ncc.data);
  }
  SetCounters(state, surface.ncc);
}

void BM_MaskedNccNaiveWindow(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const MaskedNccOptions options = WindowOptions(scene, static_cast<int>(state.range(2)));
  MaskedNccSurface surface;
  for (auto _ : state) {
    surface =
        MaskedNccNaive(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask, options);
    benchmark::DoNotOptimize(surface.ncc.data);
  }
  SetCounters(state, surface.ncc);
}

// Direct summation against FFTs over small windows, and the cost model's pick (NccMethod::kAuto):
// where the two cross, the pick should follow. Arguments: template size, image size, radius.
template <NccMethod kMethod>
void BM_MaskedNccWindowBy(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const MaskedNccOptions options = WindowOptions(scene, static_cast<int>(state.range(2)), kMethod);
  MaskedNccSurface surface;
  for (auto _ : state) {
    surface = MaskedNcc(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask, options);
    benchmark::DoNotOptimize(surface.ncc.data);
  }
  SetCounters(state, surface.ncc);
  state.counters["direct_picked"] =
      DirectNccIsCheaper(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask, options);
}

void BM_FindPeak(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const MaskedNccSurface surface =
      MaskedNcc(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask);
  for (auto _ : state) {
    const NccPeak peak = FindPeak(surface);
    benchmark::DoNotOptimize(peak.value);
  }
  SetCounters(state, surface.ncc);
}

template <int kMethod>
void BM_OpenCvMatchTemplate(benchmark::State& state) {
  const Scene& scene = GetScene(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  cv::Mat result;
  for (auto _ : state) {
    cv::matchTemplate(scene.fixed, scene.moving, result, kMethod, scene.moving_mask);
    benchmark::DoNotOptimize(result.data);
  }
  SetCounters(state, result);
}

// Every benchmark: milliseconds of wall time (the work runs on all cores), median of 3
// repetitions, since the machines these run on are shared.
void Common(benchmark::internal::Benchmark* b) {
  b->Unit(benchmark::kMillisecond)->UseRealTime()->Repetitions(3)->ReportAggregatesOnly(true);
}

void CrossOver(benchmark::internal::Benchmark* b) {
  Common(b);
  for (const int templ : {32, 128}) {
    for (const int radius : {1, 2, 4, 8}) b->Args({templ, 4 * templ, radius});
  }
}

void Sizes(benchmark::internal::Benchmark* b) {
  Common(b);
  b->Args({256, 1024})->Args({64, 256})->Args({128, 256});
}

BENCHMARK(BM_MaskedNccFft)->Apply(Sizes);
BENCHMARK(BM_MaskedNccFftInside<FftPrecision::kDouble>)->Apply(Sizes);
BENCHMARK(BM_MaskedNccFftInside<FftPrecision::kSingle>)->Apply(Sizes);
BENCHMARK(BM_OpenCvMatchTemplate<cv::TM_CCORR_NORMED>)->Apply(Sizes);
BENCHMARK(BM_OpenCvMatchTemplate<cv::TM_CCOEFF_NORMED>)->Apply(Sizes);
BENCHMARK(BM_MaskedNccNaive)->Apply(Common)->Args({64, 256});
BENCHMARK(BM_MaskedNccFftWindow)->Apply(Common)->Args({256, 1024, 16});
BENCHMARK(BM_MaskedNccNaiveWindow)->Apply(Common)->Args({256, 1024, 16});
BENCHMARK(BM_FindPeak)->Apply(Common)->Args({256, 1024});
BENCHMARK(BM_MaskedNccWindowBy<NccMethod::kFft>)->Apply(CrossOver);
BENCHMARK(BM_MaskedNccWindowBy<NccMethod::kDirect>)->Apply(CrossOver);
BENCHMARK(BM_MaskedNccWindowBy<NccMethod::kAuto>)->Apply(CrossOver);

// Console output as usual, and the real time [ms] of every run kept for the ratio table.
class RecordingReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    // The median where there are repetitions, else the single run; keyed without the
    // aggregate suffix and the repetition count.
    for (const Run& run : runs) {
      const bool median = run.run_type == Run::RT_Aggregate && run.aggregate_name == "median";
      std::string name = run.run_name.str();
      if (const size_t at = name.find("/repeats:"); at != std::string::npos) {
        name.erase(at, name.find('/', at + 1) - at);
      }
      if (!median && (run.run_type != Run::RT_Iteration || times_ms.count(name) > 0)) continue;
      times_ms[name] = run.GetAdjustedRealTime() *
                       benchmark::GetTimeUnitMultiplier(benchmark::kMillisecond) /
                       benchmark::GetTimeUnitMultiplier(run.time_unit);
    }
  }
  std::map<std::string, double> times_ms;
};

void PrintRatio(const std::map<std::string, double>& times, const std::string& what,
                const std::string& name, const std::string& baseline_what,
                const std::string& baseline) {
  const auto a = times.find(name);
  const auto b = times.find(baseline);
  if (a == times.end() || b == times.end()) return;  // Filtered out.
  std::printf("%-45s %9.2f ms  vs %-30s %9.2f ms  ratio %6.2fx\n", what.c_str(), a->second,
              baseline_what.c_str(), b->second, a->second / b->second);
}

void PrintSummary(const std::map<std::string, double>& t) {
  std::printf("\nRatios (time / baseline time; < 1 means faster than the baseline)\n");
  for (const char* size : {"256/1024", "64/256"}) {
    const std::string s = size;
    PrintRatio(t, "masked NCC FFT " + s, "BM_MaskedNccFft/" + s + "/real_time",
               "OpenCV TM_CCORR_NORMED+mask",
               "BM_OpenCvMatchTemplate<cv::TM_CCORR_NORMED>/" + s + "/real_time");
    PrintRatio(t, "masked NCC FFT " + s, "BM_MaskedNccFft/" + s + "/real_time",
               "OpenCV TM_CCOEFF_NORMED+mask",
               "BM_OpenCvMatchTemplate<cv::TM_CCOEFF_NORMED>/" + s + "/real_time");
    PrintRatio(t, "masked NCC FFT, OpenCV's shifts " + s,
               "BM_MaskedNccFftInside/" + s + "/real_time", "OpenCV TM_CCORR_NORMED+mask",
               "BM_OpenCvMatchTemplate<cv::TM_CCORR_NORMED>/" + s + "/real_time");
    PrintRatio(t, "masked NCC FFT, OpenCV's shifts " + s,
               "BM_MaskedNccFftInside/" + s + "/real_time", "OpenCV TM_CCOEFF_NORMED+mask",
               "BM_OpenCvMatchTemplate<cv::TM_CCOEFF_NORMED>/" + s + "/real_time");
  }
  PrintRatio(t, "masked NCC FFT 64/256", "BM_MaskedNccFft/64/256/real_time",
             "masked NCC naive 64/256", "BM_MaskedNccNaive/64/256/real_time");
  PrintRatio(t, "masked NCC FFT 256/1024, +-16 px window",
             "BM_MaskedNccFftWindow/256/1024/16/real_time", "naive, same window",
             "BM_MaskedNccNaiveWindow/256/1024/16/real_time");
  PrintRatio(t, "masked NCC FFT 256/1024, +-16 px window",
             "BM_MaskedNccFftWindow/256/1024/16/real_time", "FFT, all shifts",
             "BM_MaskedNccFft/256/1024/real_time");
  PrintRatio(t, "FindPeak 256/1024 surface", "BM_FindPeak/256/1024/real_time",
             "masked NCC FFT 256/1024", "BM_MaskedNccFft/256/1024/real_time");
}

// Not timed: the masked NCC finds the true shift on the benchmark scenes, as OpenCV does.
void PrintSanityCheck() {
  std::printf("\nSanity check (true shift; masked NCC peak; OpenCV TM_CCORR_NORMED peak)\n");
  for (const auto& [t, i] : {std::pair{256, 1024}, std::pair{64, 256}}) {
    const Scene& scene = GetScene(t, i);
    const NccPeak peak =
        FindPeak(MaskedNcc(scene.fixed, scene.fixed_mask, scene.moving, scene.moving_mask));
    cv::Mat result;
    cv::matchTemplate(scene.fixed, scene.moving, result, cv::TM_CCORR_NORMED, scene.moving_mask);
    cv::Point best;
    cv::minMaxLoc(result, nullptr, nullptr, nullptr, &best);
    std::printf("%d/%d: (%d, %d); %s; (%d, %d)\n", t, i, scene.true_x, scene.true_y,
                peak.BriefReport().c_str(), best.x, best.y);
  }
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  areomap::RecordingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  areomap::PrintSummary(reporter.times_ms);
  areomap::PrintSanityCheck();
  benchmark::Shutdown();
  return 0;
}
