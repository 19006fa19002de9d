// The report of a mission run: one self-contained HTML page (pictures embedded as data URIs, no
// scripts, no network) built only from the files `areomap run` left in its folder, so it can be
// re-made at any time (`areomap report DIR`).
//
// Sections: key figures (traverse length, end-point errors against truth when known, sigma0),
// the traverse map over the orbital image, the anchored sites and per-leg RE tables (the
// adjustment's CSVs), each site's registration (verdict, shift with 1 sigma, correlation, the
// correlation surface), each leg's tie points and fault-detection table (Table 4.5 rules with
// value, threshold and verdict), the whole-traverse orthomosaic and DTM thumbnails with their
// differences from the orbital DTM (telemetry vs adjusted poses), the crater overlay with its
// score against truth when craters were detected, and the wall time per stage.
// Failure: throws areomap::Error naming the folder when summary.json is missing or not a run's.
#pragma once

#include <filesystem>

namespace areomap {

// Writes run_dir/report.html atomically.
void WriteRunReport(const std::filesystem::path& run_dir);

}  // namespace areomap
