#include "areomap/adjustment/bundle_io.h"

#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>

#include "areomap/map/error.h"

namespace areomap {
namespace {

using nlohmann::json;

// Where a value sits, for messages: "<file>: tie_points[3].site_a".
struct Where {
  std::string file;
  std::string path;
  Where operator/(const std::string& key) const {
    return {file, path.empty() ? key : path + "." + key};
  }
  Where operator[](size_t i) const { return {file, path + "[" + std::to_string(i) + "]"}; }
  [[noreturn]] void Fail(const std::string& expected) const {
    throw Error(file + ": " + path + ": expected " + expected);
  }
};

const json& Field(const json& j, const std::string& key, const Where& where) {
  if (!j.is_object() || !j.contains(key)) (where / key).Fail("a value (missing)");
  return j.at(key);
}

double Number(const json& j, const Where& where) {
  if (!j.is_number()) where.Fail("a number");
  return j.get<double>();
}

// An int, also in range: get<int>() would wrap 4294967296 to site 0.
int Integer(const json& j, const Where& where) {
  constexpr long long kMin = std::numeric_limits<int>::min();
  constexpr long long kMax = std::numeric_limits<int>::max();
  if (!j.is_number_integer() ||
      (j.is_number_unsigned() ? j.get<unsigned long long>() > static_cast<unsigned long long>(kMax)
                              : j.get<long long>() < kMin || j.get<long long>() > kMax)) {
    where.Fail("an integer in [" + std::to_string(kMin) + ", " + std::to_string(kMax) + "]");
  }
  return j.get<int>();
}

std::string Text(const json& j, const std::string& key, const std::string& fallback,
                 const Where& where) {
  if (!j.contains(key)) return fallback;
  if (!j.at(key).is_string()) (where / key).Fail("a string");
  return j.at(key).get<std::string>();
}

template <int N>
Eigen::Matrix<double, N, 1> Vector(const json& j, const Where& where) {
  if (!j.is_array() || j.size() != N) where.Fail("an array of " + std::to_string(N) + " numbers");
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = Number(j[static_cast<size_t>(i)], where[i]);
  return v;
}

// A position [m] in a site, the traverse or MBF: within 10,000 km of its frame's origin (farther
// than across Mars), so that the adjustment's squares and covariances stay finite.
Eigen::Vector3d Position(const json& j, const Where& where) {
  constexpr double kMaxM = 1e7;
  const Eigen::Vector3d v = Vector<3>(j, where);
  if (!(v.cwiseAbs().maxCoeff() <= kMaxM)) {
    where.Fail("coordinates within 1e7 m (10,000 km) of the frame's origin");
  }
  return v;
}

template <int N>
Eigen::Matrix<double, N, N> Matrix(const json& j, const Where& where) {
  const std::string expected =
      "a " + std::to_string(N) + "x" + std::to_string(N) + " array of numbers";
  if (!j.is_array() || j.size() != N) where.Fail(expected);
  Eigen::Matrix<double, N, N> m;
  for (int r = 0; r < N; ++r) {
    const json& row = j[static_cast<size_t>(r)];
    if (!row.is_array() || row.size() != N) where.Fail(expected);
    for (int c = 0; c < N; ++c) m(r, c) = Number(row[static_cast<size_t>(c)], where[r][c]);
  }
  if (!(m - m.transpose()).isZero(1e-9 * (1.0 + m.cwiseAbs().maxCoeff()))) {
    where.Fail("a symmetric matrix");
  }
  return m;
}

Eigen::Quaterniond Rotation(const json& j, const Where& where) {
  if (!j.contains("rotation_wxyz")) return Eigen::Quaterniond::Identity();
  const Eigen::Vector4d q = Vector<4>(j.at("rotation_wxyz"), where / "rotation_wxyz");
  if (q.norm() < 1e-9) (where / "rotation_wxyz").Fail("a non-zero quaternion (w, x, y, z)");
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
}

// A 6x6 pose covariance: "covariance" (rad^2, m^2) or "sigma_rotation_deg" + "sigma_position_m".
Matrix6d PoseCovariance(const json& j, const Where& where) {
  if (j.contains("covariance")) return Matrix<6>(j.at("covariance"), where / "covariance");
  const Eigen::Vector3d rotation =
      Vector<3>(Field(j, "sigma_rotation_deg", where), where / "sigma_rotation_deg");
  const Eigen::Vector3d position =
      Vector<3>(Field(j, "sigma_position_m", where), where / "sigma_position_m");
  if ((rotation.array() <= 0.0).any() || (position.array() <= 0.0).any()) {
    where.Fail("positive sigma_rotation_deg and sigma_position_m");
  }
  return PoseCovarianceFromSigmas(rotation.unaryExpr([](double d) { return RadFromDeg(d); }),
                                  position);
}

const json& Array(const json& j, const std::string& key, const Where& where) {
  static const json empty = json::array();
  if (!j.contains(key)) return empty;
  if (!j.at(key).is_array()) (where / key).Fail("an array");
  return j.at(key);
}

json ReadJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": no such file or not readable");
  try {
    return json::parse(in);
  } catch (const json::exception& e) {  // parse_error, or out_of_range for a number like 1e99999.
    throw Error(path.string() + ": not valid JSON: " + e.what());
  }
}

void ReadHeader(const json& doc, const Where& w, BundleInputFile& out) {
  if (doc.contains("format") && doc.at("format") != "areomap-adjustment") {
    (w / "format").Fail("\"areomap-adjustment\"");
  }
  BundleInput& input = out.input;
  if (doc.contains("body")) {
    const json& body = doc.at("body");
    if (body.is_string()) {
      input.body = Body::FromName(body.get<std::string>());
    } else {
      input.body = Body{Text(body, "name", "custom", w / "body"),
                        Number(Field(body, "a_m", w / "body"), w / "body" / "a_m"),
                        Number(Field(body, "b_m", w / "body"), w / "body" / "b_m")};
      input.body.Check();
    }
  }
  const Where wo = w / "origin";
  const json& origin = Field(doc, "origin", w);
  input.origin = Geographic{RadFromDeg(Number(Field(origin, "lat_deg", wo), wo / "lat_deg")),
                            RadFromDeg(Number(Field(origin, "lon_deg", wo), wo / "lon_deg")),
                            Number(Field(origin, "h_m", wo), wo / "h_m")};
  if (!IsValid(input.origin)) (wo / "lat_deg").Fail("a latitude in [-90, 90] degrees");
  const json& sites = Field(doc, "sites", w);
  if (!sites.is_array() || sites.empty()) (w / "sites").Fail("a non-empty array of sites");
  for (size_t i = 0; i < sites.size(); ++i) {
    const Where ws = (w / "sites")[i];
    if (Integer(Field(sites[i], "site", ws), ws / "site") != static_cast<int>(i)) {
      (ws / "site").Fail(std::to_string(i) + " (sites are listed in order from 0)");
    }
    input.initial_poses.emplace_back(
        Rotation(sites[i], ws), Position(Field(sites[i], "position_m", ws), ws / "position_m"));
  }
  input.site_count = static_cast<int>(sites.size());
  if (doc.contains("site0_prior")) {
    input.site0_prior_covariance = PoseCovariance(doc.at("site0_prior"), w / "site0_prior");
  }
}

// The document's "tie_points" (none when absent), appended to `ties`; ids default to "tie<k>"
// with k counted over `ties`.
void ReadTiePointArray(const json& doc, const Where& w, std::vector<TiePoint>& ties) {
  const json& array = Array(doc, "tie_points", w);
  for (size_t i = 0; i < array.size(); ++i) {
    const Where wt = (w / "tie_points")[i];
    const json& t = array[i];
    TiePoint tie;
    tie.id = Text(t, "id", "tie" + std::to_string(ties.size()), wt);
    tie.site_a = Integer(Field(t, "site_a", wt), wt / "site_a");
    tie.site_b = Integer(Field(t, "site_b", wt), wt / "site_b");
    tie.position_in_a = Position(Field(t, "position_in_a_m", wt), wt / "position_in_a_m");
    tie.covariance_in_a = Matrix<3>(Field(t, "covariance_in_a_m2", wt), wt / "covariance_in_a_m2");
    tie.position_in_b = Position(Field(t, "position_in_b_m", wt), wt / "position_in_b_m");
    tie.covariance_in_b = Matrix<3>(Field(t, "covariance_in_b_m2", wt), wt / "covariance_in_b_m2");
    tie.source = Text(t, "source", tie.source, wt);
    ties.push_back(tie);
  }
}

void ReadPriorArray(const json& doc, const Where& w, std::vector<RelativePosePrior>& priors) {
  const json& array = Array(doc, "priors", w);
  for (size_t i = 0; i < array.size(); ++i) {
    const Where wp = (w / "priors")[i];
    const json& p = array[i];
    RelativePosePrior prior;
    prior.site_a = Integer(Field(p, "site_a", wp), wp / "site_a");
    prior.site_b = Integer(Field(p, "site_b", wp), wp / "site_b");
    prior.a_from_b =
        Rigid3d(Rotation(p, wp), Position(Field(p, "position_m", wp), wp / "position_m"));
    prior.covariance = PoseCovariance(p, wp);
    prior.source = Text(p, "source", prior.source, wp);
    priors.push_back(prior);
  }
}

// A control point's MBF position: from "position_traverse_m", "position_mbf_m" or
// "lat_deg"/"lon_deg"/"h_m", the first present.
Eigen::Vector3d ControlPositionMbf(const json& c, const Where& wc, const Body& body,
                                   const Rigid3d& mbf_from_traverse) {
  if (c.contains("position_traverse_m")) {
    return mbf_from_traverse * Position(c.at("position_traverse_m"), wc / "position_traverse_m");
  }
  if (c.contains("position_mbf_m")) return Position(c.at("position_mbf_m"), wc / "position_mbf_m");
  const Geographic g{RadFromDeg(Number(Field(c, "lat_deg", wc), wc / "lat_deg")),
                     RadFromDeg(Number(Field(c, "lon_deg", wc), wc / "lon_deg")),
                     Number(Field(c, "h_m", wc), wc / "h_m")};
  if (!IsValid(g)) (wc / "lat_deg").Fail("a latitude in [-90, 90] degrees");
  return MbfFromGeographic(body, g);
}

// A control point's MBF covariance: from "covariance_mbf_m2", "covariance_traverse_m2" or
// "sigma_horizontal_m"/"sigma_vertical_m" (local level frame at `position_mbf`).
Eigen::Matrix3d ControlCovarianceMbf(const json& c, const Where& wc, const Body& body,
                                     const Rigid3d& mbf_from_traverse,
                                     const Eigen::Vector3d& position_mbf) {
  if (c.contains("covariance_mbf_m2")) {
    return Matrix<3>(c.at("covariance_mbf_m2"), wc / "covariance_mbf_m2");
  }
  if (c.contains("covariance_traverse_m2")) {
    const Eigen::Matrix3d r = mbf_from_traverse.RotationMatrix();
    return r * Matrix<3>(c.at("covariance_traverse_m2"), wc / "covariance_traverse_m2") *
           r.transpose();
  }
  // Horizontal and vertical sigmas in the local level frame at the point.
  const double h = Number(Field(c, "sigma_horizontal_m", wc), wc / "sigma_horizontal_m");
  const double v = Number(Field(c, "sigma_vertical_m", wc), wc / "sigma_vertical_m");
  if (!(h > 0.0) || !(v > 0.0)) (wc / "sigma_horizontal_m").Fail("positive sigmas");
  const Eigen::Matrix3d mbf_from_enu =
      EnuFromMbf(body, GeographicFromMbf(body, position_mbf)).RotationMatrix().transpose();
  return mbf_from_enu * Eigen::Vector3d(h * h, h * h, v * v).asDiagonal() *
         mbf_from_enu.transpose();
}

void ReadControlPointArray(const json& doc, const Where& w, BundleInput& input) {
  const json& controls = Array(doc, "control_points", w);
  const Rigid3d mbf_from_traverse = SiteFromMbf(input.body, input.origin).Inverse();
  for (size_t i = 0; i < controls.size(); ++i) {
    const Where wc = (w / "control_points")[i];
    const json& c = controls[i];
    ControlPoint control;
    control.id = Text(c, "id", "control" + std::to_string(input.control_points.size()), wc);
    control.site = Integer(Field(c, "site", wc), wc / "site");
    control.position_in_site =
        Position(Field(c, "position_in_site_m", wc), wc / "position_in_site_m");
    control.covariance_in_site =
        Matrix<3>(Field(c, "covariance_in_site_m2", wc), wc / "covariance_in_site_m2");
    control.position_mbf = ControlPositionMbf(c, wc, input.body, mbf_from_traverse);
    control.covariance_mbf =
        ControlCovarianceMbf(c, wc, input.body, mbf_from_traverse, control.position_mbf);
    control.source = Text(c, "source", control.source, wc);
    input.control_points.push_back(control);
  }
}

void ReadHeightArray(const json& doc, const Where& w, std::vector<SiteHeight>& out) {
  const json& heights = Array(doc, "heights", w);
  for (size_t i = 0; i < heights.size(); ++i) {
    const Where wh = (w / "heights")[i];
    SiteHeight h;
    h.site = Integer(Field(heights[i], "site", wh), wh / "site");
    h.height_m = Number(Field(heights[i], "h_m", wh), wh / "h_m");
    h.sigma_m = Number(Field(heights[i], "sigma_m", wh), wh / "sigma_m");
    h.source = Text(heights[i], "source", h.source, wh);
    out.push_back(h);
  }
}

ImageObservation ReadImageObservation(const json& o, const Where& wi) {
  ImageObservation image;
  const json& landmark = Field(o, "landmark", wi);
  if (!landmark.is_string()) (wi / "landmark").Fail("a tie point or control point id");
  image.landmark_id = landmark.get<std::string>();
  image.site = Integer(Field(o, "site", wi), wi / "site");
  image.image = Text(o, "image", "", wi);
  image.pixel = Vector<2>(Field(o, "pixel", wi), wi / "pixel");
  image.sigma_px = Number(Field(o, "sigma_px", wi), wi / "sigma_px");
  const Where wc = wi / "camera";
  const json& camera = Field(o, "camera", wi);
  CahvorModel& m = image.camera_in_site;
  m.c = Vector<3>(Field(camera, "c", wc), wc / "c");
  m.a = Vector<3>(Field(camera, "a", wc), wc / "a");
  m.h = Vector<3>(Field(camera, "h", wc), wc / "h");
  m.v = Vector<3>(Field(camera, "v", wc), wc / "v");
  m.o = camera.contains("o") ? Vector<3>(camera.at("o"), wc / "o") : m.a;
  m.r = camera.contains("r") ? Vector<3>(camera.at("r"), wc / "r") : Eigen::Vector3d::Zero();
  return image;
}

// The document's "truth": one position per site, or none.
void ReadTruthArray(const json& doc, const Where& w, BundleInputFile& out) {
  const json& truth = Array(doc, "truth", w);
  if (truth.empty()) return;
  const int site_count = out.input.site_count;
  out.truth.assign(static_cast<size_t>(site_count), Eigen::Vector3d::Constant(std::nan("")));
  for (size_t i = 0; i < truth.size(); ++i) {
    const Where wt = (w / "truth")[i];
    const int site = Integer(Field(truth[i], "site", wt), wt / "site");
    if (site < 0 || site >= site_count) (wt / "site").Fail("a listed site");
    out.truth[static_cast<size_t>(site)] =
        Position(Field(truth[i], "position_m", wt), wt / "position_m");
  }
  for (const Eigen::Vector3d& t : out.truth) {
    if (!t.allFinite()) (w / "truth").Fail("a position for every site");
  }
}

void ReadSections(const json& doc, const Where& w, BundleInputFile& out) {
  BundleInput& input = out.input;
  ReadPriorArray(doc, w, input.priors);
  ReadTiePointArray(doc, w, input.tie_points);
  ReadControlPointArray(doc, w, input);
  ReadHeightArray(doc, w, input.heights);
  const json& images = Array(doc, "image_observations", w);
  for (size_t i = 0; i < images.size(); ++i) {
    input.image_observations.push_back(
        ReadImageObservation(images[i], (w / "image_observations")[i]));
  }
  ReadTruthArray(doc, w, out);
}

json ToJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

template <int N>
json ToJson(const Eigen::Matrix<double, N, N>& m) {
  json rows = json::array();
  for (int r = 0; r < N; ++r) {
    json row = json::array();
    for (int c = 0; c < N; ++c) row.push_back(m(r, c));
    rows.push_back(row);
  }
  return rows;
}

json ToJson(const Eigen::Quaterniond& q) { return {q.w(), q.x(), q.y(), q.z()}; }

}  // namespace

BundleInputFile ReadBundleInput(const std::vector<std::filesystem::path>& paths) {
  if (paths.empty()) throw Error("no adjustment input file given");
  BundleInputFile out;
  std::map<std::string, std::string> file_of_point;  // Point id -> the file that defines it.
  for (size_t i = 0; i < paths.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      std::error_code ec;
      if (std::filesystem::equivalent(paths[i], paths[j], ec)) {
        throw Error(paths[i].string() + ": given twice (as input " + std::to_string(j + 1) +
                    " and " + std::to_string(i + 1) + "); expected each input file once");
      }
    }
    const json doc = ReadJson(paths[i]);
    const Where where{paths[i].string(), ""};
    if (!doc.is_object()) throw Error(paths[i].string() + ": expected a JSON object");
    if (i == 0) ReadHeader(doc, where, out);
    const size_t ties_before = out.input.tie_points.size();
    const size_t controls_before = out.input.control_points.size();
    ReadSections(doc, where, out);
    const auto claim = [&](const std::string& id, const char* section) {
      const auto [it, inserted] = file_of_point.emplace(id, paths[i].string());
      if (!inserted) {
        throw Error(paths[i].string() + ": " + section + " id '" + id + "' is already defined" +
                    (it->second == paths[i].string() ? std::string() : " in " + it->second) +
                    "; expected every tie and control point id once");
      }
    };
    for (size_t k = ties_before; k < out.input.tie_points.size(); ++k) {
      claim(out.input.tie_points[k].id, "tie_points");
    }
    for (size_t k = controls_before; k < out.input.control_points.size(); ++k) {
      claim(out.input.control_points[k].id, "control_points");
    }
  }
  try {
    out.input.Check();
  } catch (const Error& e) {
    throw Error(paths.front().string() + ": " + e.what());
  }
  return out;
}

std::vector<TiePoint> ReadTiePoints(const std::filesystem::path& path) {
  const json doc = ReadJson(path);
  const Where where{path.string(), ""};
  if (!doc.is_object()) throw Error(path.string() + ": expected a JSON object");
  std::vector<TiePoint> ties;
  ReadTiePointArray(doc, where, ties);
  return ties;
}

json TiePointsToJson(const std::vector<TiePoint>& tie_points) {
  json ties = json::array();
  for (const TiePoint& t : tie_points) {
    ties.push_back({{"id", t.id},
                    {"site_a", t.site_a},
                    {"site_b", t.site_b},
                    {"position_in_a_m", ToJson(t.position_in_a)},
                    {"covariance_in_a_m2", ToJson<3>(t.covariance_in_a)},
                    {"position_in_b_m", ToJson(t.position_in_b)},
                    {"covariance_in_b_m2", ToJson<3>(t.covariance_in_b)},
                    {"source", t.source}});
  }
  return ties;
}

json ControlPointsToJson(const std::vector<ControlPoint>& control_points) {
  json controls = json::array();
  for (const ControlPoint& c : control_points) {
    controls.push_back({{"id", c.id},
                        {"site", c.site},
                        {"position_in_site_m", ToJson(c.position_in_site)},
                        {"covariance_in_site_m2", ToJson<3>(c.covariance_in_site)},
                        {"position_mbf_m", ToJson(c.position_mbf)},
                        {"covariance_mbf_m2", ToJson<3>(c.covariance_mbf)},
                        {"source", c.source}});
  }
  return controls;
}

json BundleInputToJson(const BundleInput& input, const std::vector<Eigen::Vector3d>& truth) {
  json sites = json::array();
  for (int s = 0; s < input.site_count; ++s) {
    const Rigid3d& pose = input.initial_poses.at(static_cast<size_t>(s));
    sites.push_back({{"site", s},
                     {"position_m", ToJson(pose.translation)},
                     {"rotation_wxyz", ToJson(pose.rotation)}});
  }
  json priors = json::array();
  for (const RelativePosePrior& p : input.priors) {
    priors.push_back({{"site_a", p.site_a},
                      {"site_b", p.site_b},
                      {"position_m", ToJson(p.a_from_b.translation)},
                      {"rotation_wxyz", ToJson(p.a_from_b.rotation)},
                      {"covariance", ToJson<6>(p.covariance)},
                      {"source", p.source}});
  }
  const json ties = TiePointsToJson(input.tie_points);
  const json controls = ControlPointsToJson(input.control_points);
  json heights = json::array();
  for (const SiteHeight& h : input.heights) {
    heights.push_back(
        {{"site", h.site}, {"h_m", h.height_m}, {"sigma_m", h.sigma_m}, {"source", h.source}});
  }
  json images = json::array();
  for (const ImageObservation& o : input.image_observations) {
    const CahvorModel& m = o.camera_in_site;
    images.push_back({{"landmark", o.landmark_id},
                      {"site", o.site},
                      {"image", o.image},
                      {"pixel", {o.pixel.x(), o.pixel.y()}},
                      {"sigma_px", o.sigma_px},
                      {"camera",
                       {{"c", ToJson(m.c)},
                        {"a", ToJson(m.a)},
                        {"h", ToJson(m.h)},
                        {"v", ToJson(m.v)},
                        {"o", ToJson(m.o)},
                        {"r", ToJson(m.r)}}}});
  }
  json doc = {{"format", "areomap-adjustment"},
              {"version", 1},
              {"body", {{"name", input.body.name}, {"a_m", input.body.a}, {"b_m", input.body.b}}},
              {"origin",
               {{"lat_deg", DegFromRad(input.origin.lat)},
                {"lon_deg", DegFromRad(input.origin.lon)},
                {"h_m", input.origin.h}}},
              {"sites", sites},
              {"site0_prior", {{"covariance", ToJson<6>(input.site0_prior_covariance)}}},
              {"priors", priors},
              {"tie_points", ties},
              {"control_points", controls},
              {"heights", heights},
              {"image_observations", images}};
  if (!truth.empty()) {
    json t = json::array();
    for (size_t s = 0; s < truth.size(); ++s) {
      t.push_back({{"site", s}, {"position_m", ToJson(truth[s])}});
    }
    doc["truth"] = t;
  }
  return doc;
}

}  // namespace areomap
