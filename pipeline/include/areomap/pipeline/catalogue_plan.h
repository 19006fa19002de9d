// The crater catalogue over many images (crater_catalogue.h, crater_catalogue_merge.h) as a plan
// for many processes on many hosts (work_plan.h, docs/cluster.md): `areomap craters IMAGE...
// --out DIR --plan | --executor slurm|parallel` writes it, `areomap run-unit DIR UNIT...` runs its
// units.
//
// Stages and units (ids):
//   images  image_NNN: the crater job on the NNN-th image (from 1) into DIR/images/NNN_<stem>/
//           (RunCraterCatalogueImage); an image that fails is a failed unit (error.txt beside
//           its image.json), run again by the next pass
//   merge   merge: the merged craters.gpkg, craters.csv, images.csv and summary.json in DIR, once
//           every image unit has ended, done or failed (the stage tolerates failures: failed
//           images are rows of images.csv); the unit itself fails, after writing them, while any
//           image failed, so that a pass that mends an image merges again
// The fingerprint holds the images (path, size, modification time) and the options.
// Failure: as mission_plan.h (a plan whose images or options changed is refused).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/crater/crater_catalogue_merge.h"
#include "areomap/crater/crater_image.h"
#include "areomap/map/output_folder.h"
#include "areomap/map/progress.h"
#include "areomap/pipeline/mission_plan.h"
#include "areomap/pipeline/unit_claim.h"
#include "areomap/pipeline/work_plan.h"

namespace areomap {

// The plan of a catalogue of `images` (unit folders relative to the output folder);
// `arguments` are the craters command's options as given (recorded for run-unit to read again).
WorkPlan PlanCraterCatalogue(const std::vector<std::filesystem::path>& images,
                             std::vector<std::string> arguments);

// The output-folder policy of a planned catalogue (in place: units write into DIR/images/).
// `inputs` are the images and the list file.
OutputFolderOptions CataloguePlanFolderPolicy(std::vector<std::filesystem::path> inputs,
                                              bool overwrite);

// `areomap craters IMAGE... --out DIR --plan`: takes `out_dir` under that policy, writes
// out_dir/plan.json and records it; the same plan already there is returned as it is.
WorkPlan PlanCraterCatalogueFolder(const std::vector<std::filesystem::path>& images,
                                   const std::vector<std::filesystem::path>& inputs,
                                   const std::filesystem::path& out_dir,
                                   const std::vector<std::string>& arguments, bool overwrite);

// `areomap run-unit DIR UNIT...` on a catalogue plan: runs each named unit in order under its
// claim and records it done. `image` and `merge` must be the plan's options (read again from its
// arguments); summary.json of the merge is `summary_head` (the command's own fields) updated
// with the merge's figures. Throws areomap::Error before any unit for an id the plan lacks or a
// plan whose images or options changed.
std::vector<UnitRunRecord> RunCataloguePlanUnits(
    const std::filesystem::path& out_dir, const WorkPlan& plan, const CraterImageOptions& image,
    const CatalogueMergeOptions& merge, const nlohmann::json& summary_head,
    const std::vector<std::string>& unit_ids, const UnitClaimOptions& claims,
    const ProgressCallback& progress = nullptr);

}  // namespace areomap
