// Mission generator benchmark: orbital rendering of the demo scene on all cores against the same
// rendering limited to one thread (the serial baseline), in the same process.
//
//   build/release/bench/areomap_bench_generator
#include <cstdio>
#include <map>

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "areomap/samples/mission.h"

namespace areomap {
namespace {

struct DemoScene {
  MissionOptions options = MissionOptions::Preset("demo");
  Traverse traverse =
      PlanTraverse(options.traverse, options.telemetry, options.scene.half_extent_m, options.seed);
  Scene scene = [this] {
    SceneOptions s = options.scene;
    for (const SitePose& p : traverse.truth)
      s.rock_path.emplace_back(p.position.y(), p.position.x());
    return Scene(s);
  }();
  SceneGeoreference georef{Body::Mars2000(), Geographic{RadFromDeg(options.site_lat_deg),
                                                        RadFromDeg(options.site_lon_deg), -1900.0}};
};

const DemoScene& GetDemo() {
  static const DemoScene demo;
  return demo;
}

void BM_RenderDemoOrbital(benchmark::State& state) {
  const auto threads = static_cast<size_t>(state.range(0));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const DemoScene& demo = GetDemo();
  for (auto _ : state) {
    OrbitalProducts products =
        RenderOrbitalProducts(demo.scene, demo.georef, demo.options.scene.half_extent_m,
                              demo.options.orbital_dtm_posting_m, demo.options.orbital);
    benchmark::DoNotOptimize(products.image.bands.front().data);
  }
  state.counters["threads"] = static_cast<double>(threads);
}

}  // namespace
}  // namespace areomap

BENCHMARK(areomap::BM_RenderDemoOrbital)
    ->Arg(1)
    ->Arg(tbb::info::default_concurrency())
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  struct Recorder : benchmark::ConsoleReporter {
    std::map<long, double> ms;
    void ReportRuns(const std::vector<Run>& runs) override {
      ConsoleReporter::ReportRuns(runs);
      for (const Run& run : runs) {
        ms[static_cast<long>(run.counters.at("threads"))] =
            run.GetAdjustedRealTime() * benchmark::GetTimeUnitMultiplier(benchmark::kMillisecond) /
            benchmark::GetTimeUnitMultiplier(run.time_unit);
      }
    }
  } recorder;
  benchmark::RunSpecifiedBenchmarks(&recorder);
  if (recorder.ms.size() == 2) {
    const double serial = recorder.ms.begin()->second, parallel = recorder.ms.rbegin()->second;
    std::printf("\ndemo orbital rendering: %ld threads %.0f ms vs 1 thread %.0f ms, ratio %.2fx\n",
                recorder.ms.rbegin()->first, parallel, serial, parallel / serial);
  }
  benchmark::Shutdown();
  return 0;
}
