#include "mvtwin/core/patient_file.h"

#include <chrono>
#include <cmath>
#include <ctime>

#include "hdf5_io.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/nan.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"
#include "orifice_io.h"

namespace mvtwin {
namespace {

constexpr const char* kGridConvention =
    "u = 0..ures-1 runs once around the annulus from the anterolateral commissure (u=0) over the "
    "anterior leaflet to the posteromedial commissure (u=ures/2) and over the posterior leaflet "
    "back (clockwise seen from the atrium); v = 0 annulus .. vres-1 free edge. Arrays are indexed "
    "[frame][v][u][xyz].";

std::string pathology_names_list() {
  std::string s;
  for (int i = 0; i < kNumPathologies; ++i) {
    s += (i ? ", " : "") + std::string(pathology_name(static_cast<Pathology>(i)));
  }
  return s;
}

void write_sequence(const h5::Location& root, const ValveSequence& seq) {
  const h5::Location g = root.create_group("sequence");
  const auto F = static_cast<hsize_t>(seq.num_frames());
  const auto U = static_cast<hsize_t>(seq.ures), V = static_cast<hsize_t>(seq.vres);
  g.attr("ures", static_cast<long>(seq.ures));
  g.attr("vres", static_cast<long>(seq.vres));
  g.attr("num_frames", static_cast<long>(F));
  g.attr("end_diastole", static_cast<long>(seq.end_diastole));
  g.attr("first_closed", static_cast<long>(seq.first_closed));
  g.attr("grid_convention", std::string(kGridConvention));

  std::vector<double> t(F), lm(F * 9 * 3), ann(F * U * 3), surf(F * V * U * 3, kNaN);
  std::vector<std::uint8_t> lm_obs(F * 9), lm_assumed(F * 9), leaf_obs(F);
  for (hsize_t f = 0; f < F; ++f) {
    const ValveFrame& fr = seq.frames[f];
    t[f] = fr.time_s;
    for (int l = 0; l < kNumLandmarks; ++l) {
      lm_obs[f * 9 + l] = fr.landmark_observed[l];
      lm_assumed[f * 9 + l] = fr.landmark_observed[l] && fr.landmark_assumed[l];
      for (int k = 0; k < 3; ++k)
        lm[(f * 9 + l) * 3 + k] = fr.landmark_observed[l] ? fr.landmarks[l][k] : kNaN;
    }
    for (hsize_t u = 0; u < U; ++u) {
      for (int k = 0; k < 3; ++k) ann[(f * U + u) * 3 + k] = fr.annulus(u, k);
    }
    leaf_obs[f] = fr.la_surface.has_value();
    if (fr.la_surface) {
      const auto& P = fr.la_surface->points();
      for (hsize_t i = 0; i < U * V; ++i) {
        for (int k = 0; k < 3; ++k) surf[(f * U * V + i) * 3 + k] = P(i, k);
      }
    }
  }
  g.write("time", t, {F}, units::kTime);
  g.write("landmarks", lm, {F, 9, 3}, units::kLength);
  g.attr("description", std::string("landmark positions, NaN where landmark_observed is 0"),
         "landmarks");
  g.write("landmark_observed", lm_obs, {F, 9});
  g.write("landmark_assumed", lm_assumed, {F, 9});
  g.attr("description",
         std::string("1 where a present landmark was not seen but estimated from published anatomy "
                     "(ASSUMED: it drives the closure, check it)"),
         "landmark_assumed");
  std::vector<std::string> names(kLandmarkNames.begin(), kLandmarkNames.end());
  g.write_strings("landmark_names", names);
  g.write("annulus", ann, {F, U, 3}, units::kLength);
  g.attr("description",
         std::string("annulus curve = v=0 row of la_surface, present in every frame"), "annulus");
  g.write("leaflet_observed", leaf_obs, {F});
  g.attr("description",
         std::string("1 where the frame's leaflet surface is known; 0 where it is missing (for a "
                     "virtual patient: closing/closed frames that need the simulator)"),
         "leaflet_observed");
  g.write("la_surface", surf, {F, V, U, 3}, units::kLength);
  g.attr("description",
         std::string("atrial leaflet surface on the (u,v) grid, NaN in frames with "
                     "leaflet_observed = 0"),
         "la_surface");
  std::vector<double> rupture;
  for (const ChordaeRupture& r : seq.ruptured_chordae) {
    rupture.push_back(r.s_begin);
    rupture.push_back(r.s_end);
  }
  g.write("ruptured_chordae", rupture, {static_cast<hsize_t>(seq.ruptured_chordae.size()), 2});
  g.attr("description",
         std::string("torn marginal chordae: [s_begin, s_end) of their insertion sites around "
                     "the annulus (grid coordinate s from the anterolateral commissure)"),
         "ruptured_chordae");
  if (!seq.marginal_chordae_lengths.empty()) {
    std::vector<double> lengths;
    for (const ChordaLength& c : seq.marginal_chordae_lengths) {
      lengths.push_back(c.s);
      lengths.push_back(c.length_mm);
    }
    g.write("marginal_chordae_lengths", lengths,
            {static_cast<hsize_t>(seq.marginal_chordae_lengths.size()), 2});
    g.attr("description",
           std::string("marginal chordae lengths: (s, mm) per insertion site, s the grid "
                       "coordinate from the anterolateral commissure; the model's marginal rest "
                       "lengths start from them instead of the end-diastolic distances"),
           "marginal_chordae_lengths");
  }
}

ValveSequence read_sequence(const h5::Location& root) {
  const h5::Location g = root.open_group("sequence");
  ValveSequence seq;
  seq.ures = static_cast<int>(g.attr_long("ures"));
  seq.vres = static_cast<int>(g.attr_long("vres"));
  seq.end_diastole = static_cast<int>(g.attr_long("end_diastole"));
  seq.first_closed = static_cast<int>(g.attr_long("first_closed"));
  if (seq.ures < 8 || seq.ures % 2 || seq.vres < 3) {
    g.fail("", "ures must be even and >= 8 and vres >= 3, found ures=" + std::to_string(seq.ures) +
                   " vres=" + std::to_string(seq.vres));
  }
  std::vector<hsize_t> d;
  const std::vector<double> t = g.read_doubles("time", &d, {-1}, "(F)");
  const long F = static_cast<long>(d[0]);
  if (F == 0) g.fail("time", "the sequence has no frames");
  const long U = seq.ures, V = seq.vres;
  const auto lm = g.read_doubles("landmarks", &d, {F, 9, 3}, "(F, 9, 3)");
  const auto lm_obs = g.read_ints("landmark_observed", &d, {F, 9}, "(F, 9)");
  // Files written before landmark_assumed existed have none assumed.
  const auto lm_assumed = g.exists("landmark_assumed")
                              ? g.read_ints("landmark_assumed", &d, {F, 9}, "(F, 9)")
                              : decltype(lm_obs)(lm_obs.size(), 0);
  const auto ann = g.read_doubles("annulus", &d, {F, U, 3}, "(F, ures, 3)");
  const auto leaf_obs = g.read_ints("leaflet_observed", &d, {F}, "(F)");
  const auto surf = g.read_doubles("la_surface", &d, {F, V, U, 3}, "(F, vres, ures, 3)");

  seq.frames.resize(F);
  for (long f = 0; f < F; ++f) {
    ValveFrame& fr = seq.frames[f];
    fr.time_s = t[f];
    for (int l = 0; l < kNumLandmarks; ++l) {
      fr.landmark_observed[l] = lm_obs[f * 9 + l] != 0;
      fr.landmark_assumed[l] = fr.landmark_observed[l] && lm_assumed[f * 9 + l] != 0;
      for (int k = 0; k < 3; ++k) fr.landmarks[l][k] = lm[(f * 9 + l) * 3 + k];
      if (fr.landmark_observed[l] && !fr.landmarks[l].allFinite()) {
        g.fail("landmarks", "frame " + std::to_string(f) + ", landmark " +
                                std::string(kLandmarkNames[l]) +
                                " is marked observed but is NaN/Inf");
      }
    }
    fr.annulus.resize(U, 3);
    for (long u = 0; u < U; ++u) {
      for (int k = 0; k < 3; ++k) fr.annulus(u, k) = ann[(f * U + u) * 3 + k];
    }
    if (!fr.annulus.allFinite()) {
      g.fail("annulus", "frame " + std::to_string(f) + " has a NaN/Inf coordinate");
    }
    if (leaf_obs[f]) {
      LeafletGrid::Points P(U * V, 3);
      for (long i = 0; i < U * V; ++i) {
        for (int k = 0; k < 3; ++k) P(i, k) = surf[(f * U * V + i) * 3 + k];
        if (!P.row(i).allFinite()) {
          g.fail("la_surface", "frame " + std::to_string(f) + ", point (u=" +
                                   std::to_string(i % U) + ", v=" + std::to_string(i / U) +
                                   ") is NaN/Inf although leaflet_observed is 1");
        }
      }
      fr.la_surface = LeafletGrid(seq.ures, seq.vres, std::move(P));
    }
  }
  // Files written before ruptures were anatomy have none here (see read_truth).
  if (g.exists("ruptured_chordae")) {
    const auto r = g.read_doubles("ruptured_chordae", &d, {-1, 2}, "(k, 2)");
    for (size_t i = 0; i + 1 < r.size(); i += 2) seq.ruptured_chordae.push_back({r[i], r[i + 1]});
  }
  if (g.exists("marginal_chordae_lengths")) {
    const auto r = g.read_doubles("marginal_chordae_lengths", &d, {-1, 2}, "(k, 2)");
    for (size_t i = 0; i + 1 < r.size(); i += 2)
      seq.marginal_chordae_lengths.push_back({r[i], r[i + 1]});
  }
  seq.validate((g.file() + ": /sequence").c_str());
  return seq;
}

void write_images(const h5::Location& root, const std::vector<ImageVolume>& images) {
  if (images.empty()) return;
  const h5::Location g = root.create_group("images");
  g.attr("description", std::string("image volumes, one per frame; voxel (i,j,k) at origin + "
                                    "direction*diag(spacing)*(i,j,k), arrays indexed [k][j][i]"));
  for (size_t i = 0; i < images.size(); ++i) {
    const ImageVolume& im = images[i];
    char name[32];
    std::snprintf(name, sizeof name, "volume_%04zu", i);
    g.write(name, im.data,
            {static_cast<hsize_t>(im.size[2]), static_cast<hsize_t>(im.size[1]),
             static_cast<hsize_t>(im.size[0])},
            true);
    g.attr("spacing", std::vector<double>(im.spacing.data(), im.spacing.data() + 3), name);
    g.attr("origin", std::vector<double>(im.origin.data(), im.origin.data() + 3), name);
    std::vector<double> dir(9);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) dir[r * 3 + c] = im.direction(r, c);
    }
    g.attr("direction", dir, name);
    g.attr("time", im.time_s, name);
    g.attr("units", std::string("spacing/origin in mm, time in s"), name);
  }
}

std::vector<ImageVolume> read_images(const h5::Location& root) {
  std::vector<ImageVolume> out;
  if (!root.exists("images")) return out;
  const h5::Location g = root.open_group("images");
  for (int i = 0;; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "volume_%04d", i);
    if (!g.exists(name)) break;
    ImageVolume im;
    std::vector<hsize_t> d;
    im.data = g.read_floats(name, &d, {-1, -1, -1}, "(nz, ny, nx)");
    im.size = {static_cast<int>(d[2]), static_cast<int>(d[1]), static_cast<int>(d[0])};
    const h5::Location ds(h5::Handle(H5Oopen(g.id(), name, H5P_DEFAULT), H5Oclose), g.file(),
                          g.full(name));
    const auto sp = ds.attr_doubles("spacing"), org = ds.attr_doubles("origin"),
               dir = ds.attr_doubles("direction");
    if (sp.size() != 3 || org.size() != 3 || dir.size() != 9) {
      g.fail(name, "spacing/origin/direction attributes must have 3/3/9 values");
    }
    im.spacing = Eigen::Vector3d(sp[0], sp[1], sp[2]);
    im.origin = Eigen::Vector3d(org[0], org[1], org[2]);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) im.direction(r, c) = dir[r * 3 + c];
    }
    im.time_s = ds.attr_double("time");
    if (!(im.spacing.array() > 0).all()) g.fail(name, "spacing must be positive");
    out.push_back(std::move(im));
  }
  return out;
}

void write_truth(const h5::Location& root, const VirtualTruth& truth) {
  const h5::Location g = root.create_group("ground_truth");
  g.attr("description",
         std::string("SYNTHETIC: hidden truth of a virtual patient; calibration must not read it"));
  g.attr("pathology", std::string(pathology_name(truth.pathology)));
  g.attr("pathology_classes", pathology_names_list());
  g.attr("closed_frames", truth.closed_frames);
  if (!truth.observed_with.empty()) g.attr("observed_with", truth.observed_with);
  const h5::Location p = g.create_group("parameters");
  truth.parameters.for_each(
      [&](const std::string& name, double v, const char* unit) { p.write_scalar(name, v, unit); });
  std::vector<double> pose(16);
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) pose[r * 4 + c] = truth.pose(r, c);
  }
  g.write("pose", pose, {4, 4});
  g.attr("description",
         std::string("valve frame (x anterior, y anterolateral, z atrium) -> image space, mm"),
         "pose");
  const h5::Location a = g.create_group("anatomy", /*track_order=*/true);
  for (const auto& [name, v] : truth.anatomy) a.write_scalar(name, v, nullptr);
  if (truth.closed_orifice) h5::write_orifice(g, *truth.closed_orifice, nullptr, nullptr);
}

VirtualTruth read_truth(const h5::Location& root, std::vector<int>* legacy_ruptured) {
  const h5::Location g = root.open_group("ground_truth");
  VirtualTruth t;
  try {
    t.pathology = pathology_from_name(g.attr_string("pathology"));
  } catch (const Error& e) {
    g.fail("", e.what());
  }
  t.closed_frames = g.attr_string("closed_frames");
  if (g.has_attr("observed_with")) t.observed_with = g.attr_string("observed_with");
  if (g.exists("orifice")) {
    std::optional<LeafletGrid> la, lv;
    t.closed_orifice = h5::read_orifice(g.open_group("orifice"), &la, &lv);
  }
  const h5::Location p = g.open_group("parameters");
  t.parameters.for_each([&](const std::string& name, double& v, const char*) {
    v = p.read_scalar(name);
    if (!std::isfinite(v)) p.fail(name, "is not finite");
  });
  std::vector<hsize_t> d;
  const auto pose = g.read_doubles("pose", &d, {4, 4}, "(4, 4)");
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) t.pose(r, c) = pose[r * 4 + c];
  }
  // Files written before ruptures were anatomy: indices of the 28 default marginal chordae.
  if (g.exists("ruptured_marginal_chordae"))
    *legacy_ruptured = g.read_ints("ruptured_marginal_chordae", &d, {-1}, "(k)");
  const h5::Location a = g.open_group("anatomy");
  std::vector<std::string> names;
  auto collect = [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
    static_cast<std::vector<std::string>*>(data)->emplace_back(name);
    return 0;
  };
  // Drawing order where the writer tracked it; name order for a group edited by another tool.
  if (H5Literate(a.id(), H5_INDEX_CRT_ORDER, H5_ITER_INC, nullptr, collect, &names) < 0) {
    names.clear();
    H5Literate(a.id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect, &names);
  }
  for (const std::string& n : names) t.anatomy.emplace_back(n, a.read_scalar(n));
  return t;
}

}  // namespace

std::string_view pathology_name(Pathology p) {
  switch (p) {
    case Pathology::kNormal:
      return "normal";
    case Pathology::kProlapseElongatedChordae:
      return "prolapse_elongated_chordae";
    case Pathology::kProlapseRupturedChordae:
      return "prolapse_ruptured_chordae";
    case Pathology::kFunctionalMr:
      return "functional_mr";
    case Pathology::kStiffLeaflets:
      return "stiff_leaflets";
  }
  return "unknown";
}

Pathology pathology_from_name(std::string_view name) {
  for (int i = 0; i < kNumPathologies; ++i) {
    if (pathology_name(static_cast<Pathology>(i)) == name) return static_cast<Pathology>(i);
  }
  throw Error("unknown pathology '" + std::string(name) + "' (known: " + pathology_names_list() +
              ")");
}

std::string utc_now_iso8601() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

void write_patient(const std::filesystem::path& path, const Patient& patient) {
  patient.sequence.validate((path.string() + ": patient '" + patient.id + "'").c_str());
  if (patient.truth && !patient.synthetic) {
    throw Error(path.string() + ": patient '" + patient.id +
                "' has a virtual ground truth but is not marked synthetic");
  }
  if (patient.detected)
    patient.detected->validate(
        (path.string() + ": patient '" + patient.id + "', detected sequence").c_str());
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    h5::Location root = h5::Location::create_file(tmp);
    root.attr("format", std::string(kPatientFormat));
    root.attr("format_version", static_cast<long>(kPatientFormatVersion));
    root.attr("patient_id", patient.id);
    root.attr("synthetic", static_cast<long>(patient.synthetic));
    root.attr("data_origin",
              std::string(patient.synthetic ? "SYNTHETIC: virtual patient, not real patient data"
                                            : "real or user-provided data"));
    root.attr("mvtwin_version", patient.provenance.version.empty() ? std::string(kVersion)
                                                                   : patient.provenance.version);
    root.attr("command", patient.provenance.command);
    root.attr("created_utc", patient.provenance.created_utc);
    root.attr("seed", static_cast<long>(patient.provenance.seed));
    root.attr("source", patient.provenance.source);
    if (!patient.import_report.empty()) root.attr("import_report", patient.import_report);
    root.attr("units_length", std::string(units::kLength));
    root.attr("units_time", std::string(units::kTime));
    root.attr("units_stress", std::string(units::kStress));
    write_sequence(root, patient.sequence);
    write_images(root, patient.images);
    if (patient.truth) write_truth(root, *patient.truth);
    if (patient.detected) {
      const h5::Location g = root.create_group("detected");
      g.attr("detected_by", patient.detected_by);
      write_sequence(g, *patient.detected);
    }
  });
}

Patient read_patient(const std::filesystem::path& path, bool with_images) {
  const h5::Location root = h5::Location::open_file(path);
  if (!root.has_attr("format") || root.attr_string("format") != kPatientFormat) {
    root.fail("", std::string("not an mvtwin patient file (root attribute format != '") +
                      kPatientFormat + "')");
  }
  const long version = root.attr_long("format_version");
  if (version > kPatientFormatVersion) {
    root.fail("", "format_version " + std::to_string(version) +
                      " is newer than this mvtwin reads (" + std::to_string(kPatientFormatVersion) +
                      ")");
  }
  Patient p;
  p.id = root.attr_string("patient_id");
  p.synthetic = root.attr_long("synthetic") != 0;
  p.provenance.version = root.attr_string("mvtwin_version");
  p.provenance.command = root.attr_string("command");
  p.provenance.created_utc = root.attr_string("created_utc");
  p.provenance.seed = static_cast<std::uint64_t>(root.attr_long("seed"));
  p.provenance.source = root.attr_string("source");
  p.import_report = root.has_attr("import_report") ? root.attr_string("import_report") : "";
  p.sequence = read_sequence(root);
  if (with_images) p.images = read_images(root);
  if (root.exists("detected")) {
    const h5::Location g = root.open_group("detected");
    p.detected = read_sequence(g);
    p.detected_by = g.has_attr("detected_by") ? g.attr_string("detected_by") : "";
  }
  if (root.exists("ground_truth")) {
    if (!p.synthetic) root.fail("ground_truth", "present but the file is not marked synthetic");
    std::vector<int> legacy;
    p.truth = read_truth(root, &legacy);
    for (const int k : legacy) {
      if (k < 0 || k >= 28)
        root.fail("ground_truth/ruptured_marginal_chordae", "index out of 0..27");
      const ChordaeRupture r = marginal_chorda_rupture(k, 28);
      p.sequence.ruptured_chordae.push_back(r);
    }
  }
  return p;
}

}  // namespace mvtwin
