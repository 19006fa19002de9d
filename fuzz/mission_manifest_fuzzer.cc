// Feeds the input as mission.json to ReadMissionManifest(istream, manifest) (the reader behind
// ReadMissionManifest(folder)). The manifest sits in a scratch mission folder that holds the
// files the seeds refer to (sites/site_000/*, orbital/*, telemetry/ and truth/ CSVs), so that
// the fuzzer gets past the existence checks. Expected: areomap::Error.
#include <sstream>

#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "fuzz_support.h"

namespace {

const std::filesystem::path& MissionFolder() {
  static const std::filesystem::path folder = [] {
    using areomap::fuzz::WriteScratchFile;
    const std::string sites_csv =
        "site,north_m,east_m,down_m,heading_deg\n0,0,0,0,0\n1,10.5,-3.25,0.1,90\n";
    for (const char* name :
         {"mission/sites/site_000/NAVCAM_LEFT_00.png", "mission/sites/site_000/NAVCAM_LEFT_00.json",
          "mission/sites/site_000/NAVCAM_RIGHT_00.png",
          "mission/sites/site_000/NAVCAM_RIGHT_00.json", "mission/orbital/hirise_ortho.tif",
          "mission/orbital/hirise_dtm.tif", "mission/truth/craters.csv",
          "mission/truth/rocks.csv"}) {
      WriteScratchFile(name, "x");
    }
    WriteScratchFile("mission/telemetry/sites.csv", sites_csv);
    WriteScratchFile("mission/truth/sites.csv", sites_csv);
    return areomap::fuzz::ScratchDir() / "mission";
  }();
  return folder;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path manifest = MissionFolder() / "mission.json";
  std::istringstream in{std::string(areomap::fuzz::AsText(data, size))};
  try {
    (void)areomap::ReadMissionManifest(in, manifest);
  } catch (const areomap::Error&) {
  }
  return 0;
}
