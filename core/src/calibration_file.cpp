#include "mvtwin/core/calibration_file.h"

#include "hdf5_io.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/units.h"
#include "mvtwin/core/version.h"
#include "raw_voxels.h"
#include "result_header.h"

namespace mvtwin {
namespace {

constexpr const char* kFormat = "mvtwin-calibration";
constexpr long kFormatVersion = 1;

std::vector<double> vec(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }
/// Row-major copy of a matrix.
std::vector<double> rows(const Eigen::MatrixXd& m) {
  std::vector<double> out;
  out.reserve(static_cast<size_t>(m.size()));
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) out.push_back(m(i, j));
  return out;
}

}  // namespace

void write_calibration_file(const std::filesystem::path& path, const CalibrationRecord& r) {
  const auto n = static_cast<Eigen::Index>(r.names.size());
  const auto H = r.history_simulation.size();
  for (const Eigen::VectorXd* v : {&r.lower, &r.upper, &r.start, &r.fitted, &r.sd, &r.truth}) {
    if (v->size() != n) throw Error(path.string() + ": per-parameter arrays of different lengths");
  }
  if (static_cast<Eigen::Index>(r.units.size()) != n ||
      static_cast<Eigen::Index>(r.identified.size()) != n || r.covariance.rows() != n ||
      r.covariance.cols() != n || r.correlation.rows() != n || r.correlation.cols() != n) {
    throw Error(path.string() + ": per-parameter arrays of different lengths");
  }
  if (r.history_error_mm.size() != H || r.history_best_mm.size() != H ||
      static_cast<size_t>(r.history_x.rows()) != H || (H > 0 && r.history_x.cols() != n)) {
    throw Error(path.string() + ": history arrays of different lengths");
  }
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    h5::Location root = h5::Location::create_file(tmp);
    h5::write_result_header(root, kFormat, kFormatVersion, "calibration",
                            {r.patient_id, r.patient_file, r.synthetic, r.provenance, r.options});
    root.attr("method", r.method);
    root.attr("termination", r.termination);

    const h5::Location fit = root.create_group("fit");
    fit.attr("description",
             std::string("per fitted parameter (user units, see units): bounds, start, fitted "
                         "value, standard deviation and covariance from J^T J scaled by "
                         "noise_mm, correlation; truth is the virtual patient's hidden value "
                         "(NaN for real data); identified = 1 where the data determine it"));
    fit.write_strings("names", r.names);
    fit.write_strings("units", r.units);
    const auto N = static_cast<hsize_t>(n);
    fit.write("lower", vec(r.lower), {N});
    fit.write("upper", vec(r.upper), {N});
    fit.write("start", vec(r.start), {N});
    fit.write("fitted", vec(r.fitted), {N});
    fit.write("sd", vec(r.sd), {N});
    fit.write("truth", vec(r.truth), {N});
    fit.write("identified", r.identified, {N});
    fit.write("covariance", rows(r.covariance), {N, N});
    fit.write("correlation", rows(r.correlation), {N, N});
    fit.write_scalar("noise_mm", r.noise_mm, "mm");
    fit.write_scalar("error_before_mm", r.error_before_mm, "mm");
    fit.write_scalar("error_after_mm", r.error_after_mm, "mm");
    fit.write_scalar("simulations", r.simulations, nullptr);
    fit.write_scalar("failed_simulations", r.failed_simulations, nullptr);
    fit.write_scalar("cache_hits", r.cache_hits, nullptr);
    fit.write_scalar("wall_s", r.wall_s, "s");
    fit.write_scalar("search_simulations", r.search_simulations, nullptr);
    fit.write_scalar("search_error_before_mm", r.search_error_before_mm, "mm");
    fit.write_scalar("search_error_after_mm", r.search_error_after_mm, "mm");
    if (!r.refinement.empty()) fit.attr("refinement", r.refinement);

    const h5::Location par = root.create_group("parameters", true);
    r.parameters.for_each([&](const std::string& name, double v, const char* unit) {
      par.write_scalar(name, v, unit);
    });

    const h5::Location hist = root.create_group("history");
    hist.write("simulation", r.history_simulation, {H});
    hist.write("error_mm", r.history_error_mm, {H}, "mm (NaN: failed simulation)");
    hist.write("best_mm", r.history_best_mm, {H}, "mm");
    hist.write("x", rows(r.history_x), {H, N});
  });
}

CalibrationRecord read_calibration_file(const std::filesystem::path& path) {
  const h5::Location root = h5::Location::open_file(path);
  h5::ResultHeader h = h5::read_result_header(root, kFormat, kFormatVersion, "calibration");
  CalibrationRecord r;
  r.patient_id = std::move(h.patient_id);
  r.patient_file = std::move(h.patient_file);
  r.synthetic = h.synthetic;
  r.provenance = std::move(h.provenance);
  r.options = std::move(h.options);
  r.method = root.attr_string("method");
  r.termination = root.attr_string("termination");
  const h5::Location fit = root.open_group("fit");
  r.names = fit.read_strings("names");
  const long n = static_cast<long>(r.names.size());
  r.units = fit.read_strings("units");
  if (static_cast<long>(r.units.size()) != n) fit.fail("units", "one unit per name needed");
  std::vector<hsize_t> d;
  auto v = [&](const char* name) {
    const std::vector<double> x = fit.read_doubles(name, &d, {n}, "(n)");
    return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(x.data(), n));
  };
  auto m = [&](const char* name) {
    const std::vector<double> x = fit.read_doubles(name, &d, {n, n}, "(n, n)");
    return Eigen::MatrixXd(
        Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            x.data(), n, n));
  };
  r.lower = v("lower");
  r.upper = v("upper");
  r.start = v("start");
  r.fitted = v("fitted");
  r.sd = v("sd");
  r.truth = v("truth");
  r.identified = fit.read_ints("identified", &d, {n}, "(n)");
  r.covariance = m("covariance");
  r.correlation = m("correlation");
  r.noise_mm = fit.read_scalar("noise_mm");
  // A count stored as a double: a whole number an int holds (the fuzzers found 6e223 cast).
  auto count = [&](const std::string& name) {
    return static_cast<int>(
        raw::whole(fit.read_scalar(name), fit.file() + ": " + fit.full(name), 0, 2147483647L));
  };
  r.error_before_mm = fit.read_scalar("error_before_mm");
  r.error_after_mm = fit.read_scalar("error_after_mm");
  r.simulations = count("simulations");
  r.failed_simulations = count("failed_simulations");
  r.cache_hits = count("cache_hits");
  r.wall_s = fit.read_scalar("wall_s");
  if (fit.exists("search_simulations")) {
    r.search_simulations = count("search_simulations");
    r.search_error_before_mm = fit.read_scalar("search_error_before_mm");
    r.search_error_after_mm = fit.read_scalar("search_error_after_mm");
  }
  if (fit.has_attr("refinement")) r.refinement = fit.attr_string("refinement");
  const h5::Location par = root.open_group("parameters");
  r.parameters.for_each(
      [&](const std::string& name, double& x, const char*) { x = par.read_scalar(name); });
  if (!r.fitted.allFinite()) fit.fail("fitted", "non-finite fitted value");
  const h5::Location hist = root.open_group("history");
  r.history_simulation = hist.read_ints("simulation", &d, {-1}, "(H)");
  const long H = static_cast<long>(d[0]);
  r.history_error_mm = hist.read_doubles("error_mm", &d, {H}, "(H)");
  r.history_best_mm = hist.read_doubles("best_mm", &d, {H}, "(H)");
  const std::vector<double> x = hist.read_doubles("x", &d, {H, n}, "(H, n)");
  r.history_x =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          x.data(), H, n);
  return r;
}

}  // namespace mvtwin
