#include "mvtwin/forward/virtual_closure.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"

namespace mvtwin::forward {

ClosureOptions VirtualClosureOptions::fine_default() {
  ClosureOptions o;
  o.model.ures = 40;
  o.model.vres = 40;
  o.model.layers = 3;
  o.dt = 1e-3;                    // the smallest step, where the leaflets meet
  o.step_error_mm = 0.05;         // half the calibration model's error per step
  o.solver.pcg_tolerance = 1e-3;  // a tenth of the calibration model's linear-solve tolerance
  return o;
}

std::vector<ObservationAttempt> observation_attempts(const ClosureOptions& simulation) {
  std::vector<ObservationAttempt> out;
  out.push_back({"", simulation});
  ClosureOptions o = simulation;
  o.max_step_halvings = simulation.max_step_halvings + 3;
  o.settle_max_dt = std::max(o.dt, simulation.settle_max_dt / 4);
  auto fmt = [](double v) {
    std::ostringstream os;
    os << v;
    return os.str();
  };
  out.push_back({"retry 1: max_step_halvings " + std::to_string(o.max_step_halvings) +
                     ", settle_max_dt " + fmt(o.settle_max_dt) + " s",
                 o});
  o.dt = simulation.dt / 2;
  o.max_dt = simulation.max_dt / 2;
  o.settle_max_dt = std::max(o.dt, simulation.settle_max_dt / 4);
  o.newton_iterations = std::max(2, simulation.newton_iterations);
  o.record_every = simulation.record_every * 2;  // recorded at the same simulated times
  out.push_back({"retry 2: max_step_halvings " + std::to_string(o.max_step_halvings) +
                     ", settle_max_dt " + fmt(o.settle_max_dt) + " s, dt " + fmt(o.dt) +
                     " s, max_dt " + fmt(o.max_dt) + " s, newton_iterations " +
                     std::to_string(o.newton_iterations),
                 o});
  // The law, not the stepping: a vertex pressed edge-on harder than the contact wall holds comes
  // to rest on the other leaflet's surface itself, crosses and uncrosses it by round-off, and
  // every step is refused however small (virtual-3030-30). A tenfold wall below the contact
  // distance holds it off the surface, and a crossing less than 0.1 mm deep is left to the law.
  o = simulation;
  o.contact.wall_factor = std::min(1e4, 10 * simulation.contact.wall_factor);
  o.contact.ccd_depth_mm =
      std::max(simulation.contact.ccd_depth_mm, std::min(0.1, simulation.contact.contact_mm));
  out.push_back({"retry 3: contact_wall_factor " + fmt(o.contact.wall_factor) +
                     ", contact_ccd_depth_mm " + fmt(o.contact.ccd_depth_mm),
                 o});
  return out;
}

void simulate_observed_closure(Patient* p, const VirtualClosureOptions& opt) {
  if (!p->synthetic || !p->truth) {
    throw Error("observed closure: patient '" + p->id + "' has no virtual ground truth");
  }
  if (!(opt.noise_mm >= 0 && opt.noise_mm < 5)) {
    throw Error("observed closure: noise must be in [0, 5) mm");
  }
  if (opt.tune_normal_chordae && is_tunable_normal_valve(*p) &&
      tuning_edition(*p) != kChordaeTuningEdition) {
    const ChordaeTuning t = tune_normal_virtual_patient(p, opt.tuning);
    if (std::isnan(t.kept_eroa_mm2()))
      throw Error("observed closure of '" + p->id + "': tuning its chordae failed: " + t.failure);
  }
  ValveSequence& seq = p->sequence;
  ClosureOptions given = opt.simulation;
  // Record often enough to find each frame's state (every 0.02 s of simulated time, i.e.
  // 2 ms of the image clock at the default stretch), not every step: each record samples the
  // surface, measures the orifice and evaluates the elastic energy.
  given.record_every = std::max(1, static_cast<int>(std::lround(0.02 / given.dt)));
  ClosureResult r;
  std::string setting, failures;
  ClosureOptions o;
  for (const ObservationAttempt& a : observation_attempts(given)) {
    r = simulate_closure(seq, p->truth->parameters, a.simulation);
    if (r.summary.converged()) {
      setting = a.setting;
      o = a.simulation;
      break;
    }
    failures += std::string(failures.empty() ? "" : "; ") +
                (a.setting.empty() ? "as given" : a.setting.substr(0, a.setting.find(':'))) + ": " +
                r.summary.reason;
    if (r.summary.outcome == Outcome::kInvalidInput) break;  // no setting mends the input
  }
  if (!r.summary.converged()) {
    throw Error("observed closure of '" + p->id + "' failed with every setting tried (" + failures +
                ")");
  }
  Rng rng(p->provenance.seed * 7919 + 17);
  for (int f = seq.end_diastole + 1; f <= seq.first_closed; ++f) {
    const double t = seq.frames[f].time_s;
    const ClosureSample* best = &r.samples.front();
    for (const ClosureSample& s : r.samples) {
      if (std::abs(s.observed_time_s - t) < std::abs(best->observed_time_s - t)) best = &s;
    }
    LeafletGrid g = best->la_surface.resampled(seq.ures, seq.vres);
    // The annulus row is the frame's annulus (observed separately, exactly).
    g.points().topRows(seq.ures) = seq.frames[f].annulus;
    if (opt.noise_mm > 0) {
      const TriangleMesh tri = g.triangulate();
      Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> n =
          Eigen::MatrixXd::Zero(g.points().rows(), 3);
      for (Eigen::Index k = 0; k < tri.F.rows(); ++k) {
        const Eigen::Vector3d a = tri.V.row(tri.F(k, 0)), b = tri.V.row(tri.F(k, 1)),
                              c = tri.V.row(tri.F(k, 2));
        const Eigen::Vector3d fn = (b - a).cross(c - a);
        for (int j = 0; j < 3; ++j) n.row(tri.F(k, j)) += fn.transpose();
      }
      // Smooth noise, like a detector's: white noise smoothed over the grid (8 passes of
      // 4-neighbour averaging, u periodic), rescaled to the requested SD.
      const int U = seq.ures, V = seq.vres;
      Eigen::VectorXd w(U * V);
      for (int i = 0; i < U * V; ++i) w[i] = rng.normal();
      for (int pass = 0; pass < 8; ++pass) {
        Eigen::VectorXd s = w;
        for (int v = 0; v < V; ++v) {
          for (int u = 0; u < U; ++u) {
            double sum = w[v * U + u], cnt = 1;
            for (int du : {-1, 1}) {
              sum += w[v * U + (u + du + U) % U];
              ++cnt;
            }
            if (v > 0) sum += w[(v - 1) * U + u], ++cnt;
            if (v + 1 < V) sum += w[(v + 1) * U + u], ++cnt;
            s[v * U + u] = sum / cnt;
          }
        }
        w = s;
      }
      const double sd = std::sqrt((w.array() - w.mean()).square().mean());
      if (sd > 0) w = (w.array() - w.mean()) / sd * opt.noise_mm;
      for (Eigen::Index i = U; i < g.points().rows(); ++i) {
        const double len = n.row(i).norm();
        if (len > 0) g.points().row(i) += w[i] * n.row(i) / len;
      }
    }
    seq.frames[f].la_surface = std::move(g);
  }
  std::ostringstream os;
  os << "frames " << seq.end_diastole + 1 << ".." << seq.first_closed
     << " simulated with the hidden parameters by mvtwin (ures " << o.model.ures << ", vres "
     << o.model.vres << ", " << o.model.layers << " layers, dt " << o.dt << " s, Newton "
     << o.newton_iterations << ", contact factor " << o.contact.stiffness_factor << " wall "
     << o.contact.wall_factor << ", linear tolerance " << o.solver.pcg_tolerance
     << "), nearest recorded state to each frame time, plus " << opt.noise_mm
     << " mm Gaussian noise along the normals; later frames unobserved; simulation: "
     << r.summary.brief_report();
  if (!setting.empty()) os << "; observed by " << setting << " after: " << failures;
  p->truth->closed_frames = os.str();
  p->truth->observed_with = setting;
  p->truth->closed_orifice = r.orifice;
  seq.validate(("observed closure of '" + p->id + "'").c_str());
}

}  // namespace mvtwin::forward
