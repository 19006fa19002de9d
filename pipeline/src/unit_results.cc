#include "areomap/pipeline/unit_results.h"

#include <string>
#include <utility>

#include "areomap/landmarks/rock_output.h"
#include "areomap/map/error.h"
#include "json_fields.h"

namespace areomap::mission_run {
namespace {

using json_fields::Fields;
using json_fields::Others;
using json_fields::Put;
using nlohmann::json;

// The figure, or null when missing (a field the writer always records).
json OrNull(const Figure& figure) { return figure ? json(*figure) : json(); }

StereoPairRecord ReadPair(const Fields& f) {
  StereoPairRecord p;
  p.instrument = f.Text("instrument", "");
  p.pair = f.Integer("pair", 0);
  p.image_id = f.Integer("image_id", 0);
  p.points = f.Count("points", 0);
  p.points_buried = f.Count("points_buried", 0);
  p.points_floating = f.Count("points_floating", 0);
  p.points_kept = f.Count("points_kept", 0);
  p.point_spacing_m = f.Real("point_spacing_m", 0.0);
  p.valid_fraction = f.Real("valid_fraction", 0.0);
  return p;
}

json PairToJson(const StereoPairRecord& p) {
  return {{"instrument", p.instrument},
          {"pair", p.pair},
          {"image_id", p.image_id},
          {"points", p.points},
          {"points_buried", p.points_buried},
          {"points_floating", p.points_floating},
          {"points_kept", p.points_kept},
          {"point_spacing_m", p.point_spacing_m},
          {"valid_fraction", p.valid_fraction}};
}

// Every number of an object of wall times [s].
std::map<std::string, double> ReadSeconds(const Fields& f, const char* key) {
  std::map<std::string, double> out;
  if (const std::optional<Fields> seconds = f.Object(key)) {
    for (const auto& [stage, value] : seconds->object().items()) {
      out[stage] = seconds->Real(stage.c_str(), 0.0);
    }
  }
  return out;
}

SiteRegistrationResult ReadRegistration(const Fields& f) {
  SiteRegistrationResult r;
  r.skipped = f.Text("status", "") == "skipped";
  r.reason = f.Text("reason", "");
  if (r.skipped) {
    r.other = Others(f.object(), {"status", "reason"});
    return r;
  }
  r.matched = f.Flag("matched", false);
  r.control_points = f.Count("control_points", 0);
  r.template_pixels = f.Count("template_pixels", 0);
  r.search_radius_px = f.Integer("search_radius_px", 0);
  r.correlation = f.Recorded("correlation");
  r.peak_ratio = f.Recorded("peak_ratio");
  r.null_highest_correlation = f.Recorded("null_highest_correlation");
  r.gsd_m = f.Recorded("gsd_m");
  r.prior_sigma_m = f.Recorded("prior_sigma_m");
  r.rotation_deg = f.Recorded("rotation_deg");
  r.shift_east_m = f.Recorded("shift_east_m");
  r.shift_north_m = f.Recorded("shift_north_m");
  r.sigma_east_m = f.Recorded("sigma_east_m");
  r.sigma_north_m = f.Recorded("sigma_north_m");
  r.other =
      Others(f.object(),
             {"matched", "reason", "control_points", "template_pixels", "search_radius_px",
              "correlation", "peak_ratio", "null_highest_correlation", "gsd_m", "prior_sigma_m",
              "rotation_deg", "shift_east_m", "shift_north_m", "sigma_east_m", "sigma_north_m"});
  return r;
}

LegPriorRecord ReadLegPrior(const Fields& f) {
  LegPriorRecord p;
  p.source = f.Text("source", "");
  p.reason = f.Text("reason", "");
  p.registration_minus_telemetry_m = f.Recorded("registration_minus_telemetry_m");
  p.registration_minus_telemetry_deg = f.Recorded("registration_minus_telemetry_deg");
  if (f.Has("a_from_b_translation_m")) {
    const std::vector<double> t = f.Numbers("a_from_b_translation_m");
    if (t.size() != 3) {
      f.Fail("a_from_b_translation_m", f.object().at("a_from_b_translation_m"), "3 numbers");
    }
    p.a_from_b_translation_m = std::array<double, 3>{t[0], t[1], t[2]};
  }
  p.a_from_b_turn_deg = f.Recorded("a_from_b_turn_deg");
  p.position_sigma_m = f.Recorded("position_sigma_m");
  p.heading_sigma_deg = f.Recorded("heading_sigma_deg");
  return p;
}

json LegPriorToJson(const LegPriorRecord& p) {
  json j = {{"source", p.source}};
  if (!p.reason.empty()) j["reason"] = p.reason;
  Put(j, "registration_minus_telemetry_m", p.registration_minus_telemetry_m);
  Put(j, "registration_minus_telemetry_deg", p.registration_minus_telemetry_deg);
  if (p.a_from_b_translation_m) j["a_from_b_translation_m"] = *p.a_from_b_translation_m;
  Put(j, "a_from_b_turn_deg", p.a_from_b_turn_deg);
  Put(j, "position_sigma_m", p.position_sigma_m);
  Put(j, "heading_sigma_deg", p.heading_sigma_deg);
  return j;
}

LegPassRecord ReadPass(const Fields& f) {
  LegPassRecord p;
  p.outcome = f.Text("outcome", "?");
  p.tie_points = f.Count("tie_points", 0);
  p.rock_matches = f.Count("rock_matches", 0);
  p.relative_error_percent = f.Recorded("relative_error_percent");
  p.conformal_chi2 = f.Recorded("conformal_chi2");
  p.conformal_redundancy = f.OptionalCount("conformal_redundancy");
  p.tie_variance_factor = f.Real("tie_variance_factor", 1.0);
  p.seconds = f.Recorded("seconds");
  return p;
}

// The pass's figures into `j` (a leg's own, flat, or its "first_pass").
void PutPass(json& j, const LegPassRecord& p) {
  j["outcome"] = p.outcome;
  j["tie_points"] = p.tie_points;
  j["rock_matches"] = p.rock_matches;
  Put(j, "relative_error_percent", p.relative_error_percent);
  Put(j, "conformal_chi2", p.conformal_chi2);
  Put(j, "conformal_redundancy", p.conformal_redundancy);
  j["tie_variance_factor"] = p.tie_variance_factor;
  Put(j, "seconds", p.seconds);
}

RockExtractionSummary ReadRocks(const Fields& f) {
  RockExtractionSummary s;
  s.points = f.Integer("points", 0);
  s.peak_candidates = f.Integer("peak_candidates", 0);
  s.beyond_range = f.Integer("beyond_range", 0);
  s.too_low = f.Integer("too_low", 0);
  s.merged = f.Integer("merged", 0);
  s.rocks = f.Integer("rocks", 0);
  s.modeled = f.Integer("modeled", 0);
  return s;
}

FaultVerdict ReadVerdict(const Fields& f) {
  const std::string text = f.Text("verdict", ToString(FaultVerdict::kNotEvaluated));
  for (const FaultVerdict v : {FaultVerdict::kPass, FaultVerdict::kFail}) {
    if (text == ToString(v)) return v;
  }
  if (text != ToString(FaultVerdict::kNotEvaluated)) {
    f.Fail("verdict", f.object().at("verdict"), "\"pass\", \"fail\" or \"not evaluated\"");
  }
  return FaultVerdict::kNotEvaluated;
}

PairFaultReport ReadFaults(const Fields& f) {
  PairFaultReport report;
  report.site_a = f.Integer("site_a", -1);
  report.site_b = f.Integer("site_b", -1);
  const int code = f.Integer("outcome_code", static_cast<int>(PairOutcome::kMatched));
  if (code < 1 || code > 3) f.Fail("outcome_code", f.object().at("outcome_code"), "1, 2 or 3");
  report.outcome = static_cast<PairOutcome>(code);
  for (size_t i = 0; i < f.Array("rules").size(); ++i) {
    const Fields r = f.Element("rules", i);
    report.checks.push_back({r.Text("module", ""), r.Text("rule", ""), r.Real("value"),
                             r.Real("threshold"), r.Text("unit", ""), ReadVerdict(r),
                             r.Flag("excludes_pair", false)});
  }
  return report;
}

LegConsistency ReadLegTest(const Fields& f) {
  LegConsistency v;
  v.tested = f.Flag("tested", false);
  if (!v.tested) return v;
  v.sigma0_squared = f.Real("sigma0_squared");
  v.redundancy = f.Integer("redundancy", 0);
  v.reference_sigma0_squared = f.Real("reference_sigma0_squared");
  v.reference_redundancy = f.Integer("reference_redundancy", 0);
  v.f_statistic = f.Real("f_statistic");
  v.f_threshold = f.Real("f_threshold");
  v.first_f_statistic = f.Real("first_f_statistic");
  v.dropped = f.Integers("dropped");
  v.excluded = f.Flag("excluded", false);
  return v;
}

AdjustmentResult ReadAdjustment(const Fields& f) {
  AdjustmentResult a;
  a.sites = f.Integer("sites", 0);
  a.tie_points = f.Count("tie_points", 0);
  a.control_points = f.Count("control_points", 0);
  a.priors = f.Count("priors", 0);
  a.heights = f.Count("heights", 0);
  a.rock_tie_variance_factor = f.Real("rock_tie_variance_factor", 1.0);
  a.rejected = f.Count("rejected", 0);
  a.sites_with_priors_only = f.Count("sites_with_priors_only", 0);
  a.redundancy = f.Count("redundancy", 0);
  a.sigma0 = f.Real("sigma0");
  a.converged = f.Flag("converged", false);
  a.length_m = f.Real("length_m");
  a.largest_horizontal_sigma_m = f.Real("largest_horizontal_sigma_m");
  a.solve_seconds = f.Recorded("solve_seconds");
  a.covariance_seconds = f.Recorded("covariance_seconds");
  a.files = f.Texts("files");
  a.initial_end_error_m = f.Recorded("initial_end_error_m");
  a.adjusted_end_error_m = f.Recorded("adjusted_end_error_m");
  a.median_adjusted_leg_re = f.Recorded("median_adjusted_leg_re");
  a.median_adjusted_error_m = f.Recorded("median_adjusted_error_m");
  a.worst_adjusted_error_m = f.Recorded("worst_adjusted_error_m");
  a.sites_within_1sigma = f.OptionalCount("sites_within_1sigma");
  return a;
}

GuidedPriorRecord ReadGuidedPrior(const Fields& f) {
  return {f.Real("shift_east_m"), f.Real("shift_north_m"), f.Real("rotation_deg"),
          f.Real("sigma_m")};
}

json GuidedPriorToJson(const GuidedPriorRecord& p) {
  return {{"shift_east_m", p.shift_east_m},
          {"shift_north_m", p.shift_north_m},
          {"rotation_deg", p.rotation_deg},
          {"sigma_m", p.sigma_m}};
}

GuidedAttemptRecord ReadAttempt(const Fields& f) {
  GuidedAttemptRecord a;
  a.site = f.Integer("site", -1);
  if (const std::optional<Fields> prior = f.Object("prior")) a.prior = ReadGuidedPrior(*prior);
  a.matched = f.Flag("matched", false);
  a.reason = f.Text("reason", "");
  a.correlation = f.Number("correlation");
  a.null_highest_correlation = f.Number("null_highest_correlation");
  a.search_radius_px = f.Integer("search_radius_px", 0);
  a.control_points = f.Count("control_points", 0);
  a.turn_at_edge = f.Flag("turn_at_edge", false);
  return a;
}

json AttemptToJson(const GuidedAttemptRecord& a) {
  return {{"site", a.site},
          {"prior", GuidedPriorToJson(a.prior)},
          {"matched", a.matched},
          {"reason", a.reason},
          {"correlation", OrNull(a.correlation)},
          {"null_highest_correlation", OrNull(a.null_highest_correlation)},
          {"search_radius_px", a.search_radius_px},
          {"control_points", a.control_points},
          {"turn_at_edge", a.turn_at_edge}};
}

std::optional<TraverseDifference> ReadDifference(const Fields& f, const char* key) {
  const std::optional<Fields> d = f.Object(key);
  if (!d) return std::nullopt;
  return TraverseDifference{d->Count("cells", 0), d->Recorded("mean_m"), d->Recorded("rms_m"),
                            d->Recorded("stddev_m"), d->Recorded("median_abs_m")};
}

std::optional<TraverseCorrelation> ReadCorrelation(const Fields& f, const char* key) {
  const std::optional<Fields> c = f.Object(key);
  if (!c) return std::nullopt;
  return TraverseCorrelation{c->Count("cells", 0), c->Recorded("correlation")};
}

void PutComparisons(json& j, const ProductsUnitResult& p) {
  const auto difference = [&](const char* key, const std::optional<TraverseDifference>& d) {
    if (!d) return;
    json stats = {{"cells", d->cells}};
    Put(stats, "mean_m", d->mean_m);
    Put(stats, "rms_m", d->rms_m);
    Put(stats, "stddev_m", d->stddev_m);
    Put(stats, "median_abs_m", d->median_abs_m);
    j[key] = stats;
  };
  const auto correlation = [&](const char* key, const std::optional<TraverseCorrelation>& c) {
    if (!c) return;
    j[key] = {{"cells", c->cells}};
    Put(j[key], "correlation", c->correlation);
  };
  Put(j, "orbital_dtm", p.orbital_dtm);
  difference("dtm_minus_orbital_adjusted", p.dtm_minus_orbital_adjusted);
  difference("dtm_minus_orbital_telemetry", p.dtm_minus_orbital_telemetry);
  Put(j, "orbital_image", p.orbital_image);
  correlation("ortho_vs_orbital_adjusted", p.ortho_vs_orbital_adjusted);
  correlation("ortho_vs_orbital_telemetry", p.ortho_vs_orbital_telemetry);
}

// CraterScoreRecord's counts and figures under their names in the record.
constexpr std::pair<const char*, int64_t CraterScoreRecord::*> kScoreCounts[] = {
    {"truth", &CraterScoreRecord::truth},
    {"detected", &CraterScoreRecord::detected},
    {"matched_truth", &CraterScoreRecord::matched_truth},
    {"matched_detected", &CraterScoreRecord::matched_detected}};
constexpr std::pair<const char*, Figure CraterScoreRecord::*> kScoreFigures[] = {
    {"precision", &CraterScoreRecord::precision},
    {"recall", &CraterScoreRecord::recall},
    {"f1", &CraterScoreRecord::f1},
    {"median_center_error_px", &CraterScoreRecord::median_center_error_px}};

}  // namespace

json CraterScoreRecord::ToJson() const {
  json j = other;
  j["rule"] = rule;
  for (const auto& [key, count] : kScoreCounts) j[key] = this->*count;
  for (const auto& [key, figure] : kScoreFigures) j[key] = OrNull(this->*figure);
  return j;
}

CraterScoreRecord CraterScoreRecord::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  CraterScoreRecord s;
  s.rule = f.Text("rule", "");
  s.other = Others(f.object(), {"rule"});
  for (const auto& [key, count] : kScoreCounts) {
    s.*count = f.Count(key, 0);
    s.other.erase(key);
  }
  for (const auto& [key, figure] : kScoreFigures) {
    s.*figure = f.Number(key);
    s.other.erase(key);
  }
  return s;
}

json TieVarianceRecord::ToJson() const {
  return {{"legs", legs},
          {"chi2", chi2},
          {"redundancy", redundancy},
          {"sigma0_squared", OrNull(sigma0_squared)},
          {"sigma0_squared_upper_95", OrNull(sigma0_squared_upper_95)},
          {"applied_factor", OrNull(applied_factor)}};
}

TieVarianceRecord TieVarianceRecord::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  TieVarianceRecord t;
  t.legs = f.Count("legs", 0);
  t.redundancy = f.Count("redundancy", 0);
  t.chi2 = f.Real("chi2");  // NaN when recorded as null.
  t.sigma0_squared = f.Number("sigma0_squared");
  t.sigma0_squared_upper_95 = f.Number("sigma0_squared_upper_95");
  t.applied_factor = f.Number("applied_factor");
  return t;
}

json SiteRegistrationResult::ToJson() const {
  json j = other;
  j["reason"] = reason;
  if (skipped) {
    j["status"] = "skipped";
    return j;
  }
  j["matched"] = matched;
  j["control_points"] = control_points;
  j["template_pixels"] = template_pixels;
  j["search_radius_px"] = search_radius_px;
  Put(j, "correlation", correlation);
  Put(j, "peak_ratio", peak_ratio);
  Put(j, "null_highest_correlation", null_highest_correlation);
  Put(j, "gsd_m", gsd_m);
  Put(j, "prior_sigma_m", prior_sigma_m);
  Put(j, "rotation_deg", rotation_deg);
  Put(j, "shift_east_m", shift_east_m);
  Put(j, "shift_north_m", shift_north_m);
  Put(j, "sigma_east_m", sigma_east_m);
  Put(j, "sigma_north_m", sigma_north_m);
  return j;
}

SiteRegistrationResult SiteRegistrationResult::FromJson(const json& json_in,
                                                        const std::string& where) {
  return ReadRegistration(Fields::Top(json_in, where));
}

json SiteUnitResult::ToJson() const {
  json pair_records = json::array();
  for (const StereoPairRecord& p : pairs) pair_records.push_back(PairToJson(p));
  return {{"site", site},
          {"pairs", pair_records},
          {"points", points},
          {"coarse_points_dropped", coarse_points_dropped},
          {"dtm_known_area_m2", dtm_known_area_m2},
          {"ortho_valid_area_m2", ortho_valid_area_m2},
          {"registration", registration.ToJson()},
          {"seconds", seconds}};
}

SiteUnitResult SiteUnitResult::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  SiteUnitResult s;
  s.site = f.Integer("site", -1);
  for (size_t i = 0; i < f.Array("pairs").size(); ++i) {
    s.pairs.push_back(ReadPair(f.Element("pairs", i)));
  }
  s.points = f.Count("points", 0);
  s.coarse_points_dropped = f.Count("coarse_points_dropped", 0);
  s.dtm_known_area_m2 = f.Real("dtm_known_area_m2", 0.0);
  s.ortho_valid_area_m2 = f.Real("ortho_valid_area_m2", 0.0);
  if (const std::optional<Fields> r = f.Object("registration")) {
    s.registration = ReadRegistration(*r);
  }
  s.seconds = ReadSeconds(f, "seconds");
  return s;
}

bool LegUnitResult::operator==(const LegUnitResult& other) const {
  return ToJson() == other.ToJson();
}

json LegUnitResult::ToJson() const {
  json j = {{"site_a", site_a},
            {"site_b", site_b},
            {"telemetry_distance_m", telemetry_distance_m},
            {"rocks_a", RockExtractionSummaryToJson(rocks_a)},
            {"rocks_b", RockExtractionSummaryToJson(rocks_b)},
            {"faults", faults.ToJson()}};
  if (prior) j["prior"] = LegPriorToJson(*prior);
  PutPass(j, match);
  if (first_pass) {
    j["first_pass"] = json::object();
    PutPass(j["first_pass"], *first_pass);
  }
  if (leg_test) {
    j["leg_test"] = leg_test->ToJson();
    if (leg_test->tested) j["leg_test"]["dropped_ids"] = leg_test_dropped_ids;
  }
  return j;
}

LegUnitResult LegUnitResult::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  LegUnitResult leg;
  leg.site_a = f.Integer("site_a", -1);
  leg.site_b = f.Integer("site_b", -1);
  leg.telemetry_distance_m = f.Real("telemetry_distance_m", 0.0);
  if (const std::optional<Fields> prior = f.Object("prior")) leg.prior = ReadLegPrior(*prior);
  leg.match = ReadPass(f);
  if (const std::optional<Fields> first = f.Object("first_pass")) leg.first_pass = ReadPass(*first);
  if (const std::optional<Fields> rocks = f.Object("rocks_a")) leg.rocks_a = ReadRocks(*rocks);
  if (const std::optional<Fields> rocks = f.Object("rocks_b")) leg.rocks_b = ReadRocks(*rocks);
  if (const std::optional<Fields> faults = f.Object("faults")) leg.faults = ReadFaults(*faults);
  if (const std::optional<Fields> test = f.Object("leg_test")) {
    leg.leg_test = ReadLegTest(*test);
    leg.leg_test_dropped_ids = test->Texts("dropped_ids");
  }
  return leg;
}

json CratersUnitResult::ToJson() const {
  if (skipped) return {{"status", "skipped"}, {"reason", reason}, {"seconds", seconds}};
  json j = {{"image", image},
            {"pixel_size_m", pixel_size_m},
            {"min_diameter_m", min_diameter_m},
            {"method", method},
            {"craters", craters},
            {"files", files},
            {"sun_azimuth_source", sun_azimuth_source},
            {"sun_azimuth_deg", OrNull(sun_azimuth_deg)},
            {"seconds", seconds}};
  if (!sun_azimuth_estimate.is_null()) j["sun_azimuth_estimate"] = sun_azimuth_estimate;
  if (score) j["score"] = score->ToJson();
  return j;
}

CratersUnitResult CratersUnitResult::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  CratersUnitResult c;
  c.skipped = f.Text("status", "") == "skipped";
  c.reason = f.Text("reason", "");
  c.image = f.Text("image", "");
  c.method = f.Text("method", "");
  c.pixel_size_m = f.Real("pixel_size_m", 0.0);
  c.min_diameter_m = f.Real("min_diameter_m", 0.0);
  c.craters = f.Count("craters", 0);
  c.files = f.Texts("files");
  c.sun_azimuth_source = f.Text("sun_azimuth_source", "");
  c.sun_azimuth_deg = f.Number("sun_azimuth_deg");
  if (const std::optional<Fields> e = f.Object("sun_azimuth_estimate")) {
    c.sun_azimuth_estimate = e->object();
  }
  if (const std::optional<Fields> score = f.Object("score"))
    c.score = CraterScoreRecord::FromJson(score->object(), score->where());
  c.seconds = f.Real("seconds", 0.0);
  return c;
}

json AdjustmentResult::ToJson() const {
  json j = {{"sites", sites},
            {"tie_points", tie_points},
            {"rock_tie_variance_factor", rock_tie_variance_factor},
            {"control_points", control_points},
            {"priors", priors},
            {"heights", heights},
            {"rejected", rejected},
            {"sites_with_priors_only", sites_with_priors_only},
            {"sigma0", sigma0},
            {"redundancy", redundancy},
            {"converged", converged},
            {"length_m", length_m},
            {"largest_horizontal_sigma_m", largest_horizontal_sigma_m},
            {"files", files}};
  Put(j, "solve_seconds", solve_seconds);
  Put(j, "covariance_seconds", covariance_seconds);
  Put(j, "initial_end_error_m", initial_end_error_m);
  Put(j, "adjusted_end_error_m", adjusted_end_error_m);
  Put(j, "median_adjusted_leg_re", median_adjusted_leg_re);
  Put(j, "median_adjusted_error_m", median_adjusted_error_m);
  Put(j, "worst_adjusted_error_m", worst_adjusted_error_m);
  Put(j, "sites_within_1sigma", sites_within_1sigma);
  return j;
}

AdjustmentResult AdjustmentResult::FromJson(const json& json_in, const std::string& where) {
  return ReadAdjustment(Fields::Top(json_in, where));
}

json GuidedUnitResult::ToJson() const {
  return {{"site", site},
          {"pass", pass},
          {"prior", GuidedPriorToJson(prior)},
          {"settings",
           {{"null_windows", settings.null_windows},
            {"max_false_match", settings.max_false_match},
            {"sigma_floor_m", settings.sigma_floor_m}}},
          {"registration", registration.ToJson()}};
}

GuidedUnitResult GuidedUnitResult::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  GuidedUnitResult g;
  g.site = f.Integer("site", -1);
  g.pass = f.Integer("pass", 0);
  if (const std::optional<Fields> prior = f.Object("prior")) g.prior = ReadGuidedPrior(*prior);
  if (const std::optional<Fields> s = f.Object("settings")) {
    g.settings = {s->Integer("null_windows", 0), s->Real("max_false_match"),
                  s->Real("sigma_floor_m")};
  }
  if (const std::optional<Fields> r = f.Object("registration")) {
    g.registration = ReadRegistration(*r);
  }
  return g;
}

json GuidedPassesResult::ToJson() const {
  json pass_records = json::array();
  for (const GuidedPassRecord& p : passes) {
    json attempted = json::array();
    for (const GuidedAttemptRecord& a : p.attempted) attempted.push_back(AttemptToJson(a));
    json record = {{"pass", p.pass},
                   {"attempted", attempted},
                   {"registered", p.registered},
                   {"replaced", p.replaced}};
    if (p.adjustment) record["adjustment"] = p.adjustment->ToJson();
    pass_records.push_back(record);
  }
  return {{"registered_first_pass", registered_first_pass},
          {"first_adjustment", first_adjustment.ToJson()},
          {"passes", pass_records}};
}

GuidedPassesResult GuidedPassesResult::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  GuidedPassesResult g;
  g.registered_first_pass = f.Integers("registered_first_pass");
  if (const std::optional<Fields> a = f.Object("first_adjustment")) {
    g.first_adjustment = ReadAdjustment(*a);
  }
  for (size_t i = 0; i < f.Array("passes").size(); ++i) {
    const Fields p = f.Element("passes", i);
    GuidedPassRecord pass;
    pass.pass = p.Integer("pass", 0);
    for (size_t k = 0; k < p.Array("attempted").size(); ++k) {
      pass.attempted.push_back(ReadAttempt(p.Element("attempted", k)));
    }
    pass.registered = p.Integers("registered");
    pass.replaced = p.Integers("replaced");
    if (const std::optional<Fields> a = p.Object("adjustment"))
      pass.adjustment = ReadAdjustment(*a);
    g.passes.push_back(pass);
  }
  return g;
}

json ProductsUnitResult::ToJson() const {
  json j = {{"posting_m", posting_m},
            {"width", width},
            {"height", height},
            {"dtm_known_area_m2", dtm_known_area_m2},
            {"ortho_valid_area_m2", ortho_valid_area_m2},
            {"files", files},
            {"seconds", seconds}};
  if (!poses.empty()) j["poses"] = poses;
  PutComparisons(j, *this);
  return j;
}

ProductsUnitResult ProductsUnitResult::FromJson(const json& json_in, const std::string& where) {
  const Fields f = Fields::Top(json_in, where);
  ProductsUnitResult p;
  p.posting_m = f.Real("posting_m", 0.0);
  p.width = f.Integer("width", 0);
  p.height = f.Integer("height", 0);
  p.dtm_known_area_m2 = f.Real("dtm_known_area_m2", 0.0);
  p.ortho_valid_area_m2 = f.Real("ortho_valid_area_m2", 0.0);
  p.files = f.Texts("files");
  const json& poses = f.Array("poses");
  for (size_t i = 0; i < poses.size(); ++i) {
    const json element = {{"pose", poses[i]}};
    const std::vector<double> v = Fields(element, f.Where("poses")).Numbers("pose");
    if (v.size() != 7) f.Fail("poses", poses[i], "arrays of 7 numbers (x, y, z, qw, qx, qy, qz)");
    p.poses.push_back({v[0], v[1], v[2], v[3], v[4], v[5], v[6]});
  }
  if (f.Has("orbital_dtm")) p.orbital_dtm = f.Text("orbital_dtm", "");
  if (f.Has("orbital_image")) p.orbital_image = f.Text("orbital_image", "");
  p.dtm_minus_orbital_adjusted = ReadDifference(f, "dtm_minus_orbital_adjusted");
  p.dtm_minus_orbital_telemetry = ReadDifference(f, "dtm_minus_orbital_telemetry");
  p.ortho_vs_orbital_adjusted = ReadCorrelation(f, "ortho_vs_orbital_adjusted");
  p.ortho_vs_orbital_telemetry = ReadCorrelation(f, "ortho_vs_orbital_telemetry");
  p.seconds = ReadSeconds(f, "seconds");
  return p;
}

}  // namespace areomap::mission_run
