#include "mvtwin/core/segmentation_import.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>

#include <Eigen/Dense>

#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/version.h"

namespace mvtwin {
namespace {

using std::numbers::pi;
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Voxel {
  int i, j, k;
  Eigen::Vector3d p;
};

/// Orthonormal frame of the annulus: origin at the annulus centroid, n into the atrium.
struct PlaneFrame {
  Eigen::Vector3d c, e1, e2, n;
  Eigen::Vector2d to2d(const Eigen::Vector3d& p) const { return {e1.dot(p - c), e2.dot(p - c)}; }
  double height(const Eigen::Vector3d& p) const { return n.dot(p - c); }
  Eigen::Vector3d to3d(const Eigen::Vector2d& q, double h) const {
    return c + q.x() * e1 + q.y() * e2 + h * n;
  }
};

/// Least-squares Fourier series of order `order` through (angle, value) samples, evaluated at
/// `at`; keeps the curve closed and smooth.
Eigen::VectorXd fourier_fit(const std::vector<double>& angle, const std::vector<double>& value,
                            int order, const std::vector<double>& at) {
  const int m = 2 * order + 1;
  Eigen::MatrixXd A(angle.size(), m);
  Eigen::VectorXd b(angle.size());
  auto row = [&](double a, double* r) {
    r[0] = 1.0;
    for (int k = 1; k <= order; ++k) {
      r[2 * k - 1] = std::cos(k * a);
      r[2 * k] = std::sin(k * a);
    }
  };
  std::vector<double> r(m);
  for (size_t i = 0; i < angle.size(); ++i) {
    row(angle[i], r.data());
    for (int k = 0; k < m; ++k) A(i, k) = r[k];
    b[i] = value[i];
  }
  const Eigen::VectorXd coef = A.colPivHouseholderQr().solve(b);
  Eigen::VectorXd out(at.size());
  for (size_t i = 0; i < at.size(); ++i) {
    row(at[i], r.data());
    out[i] = Eigen::Map<const Eigen::VectorXd>(r.data(), m).dot(coef);
  }
  return out;
}

/// A 2D grid over the annulus plane holding, per pixel, the atrial-most leaflet height and the
/// label there.
struct HeightField {
  Eigen::Vector2d lo;
  double pixel = 0.5;
  int nx = 0, ny = 0;
  std::vector<double> h;  // NaN where no leaflet
  std::vector<int> label;

  int idx(int x, int y) const { return x + nx * y; }
  Eigen::Vector2d centre(int x, int y) const {
    return lo + pixel * Eigen::Vector2d(x + 0.5, y + 0.5);
  }
  bool inside(int x, int y) const { return x >= 0 && y >= 0 && x < nx && y < ny; }

  /// Height at q from pixels of label `want` (or any label when want < 0) by inverse-distance
  /// weighting over the nearest valid pixels; widens the search until something is found.
  double sample(const Eigen::Vector2d& q, int want) const {
    const int cx = static_cast<int>(std::floor((q.x() - lo.x()) / pixel));
    const int cy = static_cast<int>(std::floor((q.y() - lo.y()) / pixel));
    for (int r = 1; r <= 40; ++r) {
      double sw = 0.0, sh = 0.0;
      for (int y = cy - r; y <= cy + r; ++y) {
        for (int x = cx - r; x <= cx + r; ++x) {
          if (!inside(x, y)) continue;
          const int i = idx(x, y);
          if (std::isnan(h[i]) || (want >= 0 && label[i] != want)) continue;
          const double w = 1.0 / (0.1 * pixel * pixel + (centre(x, y) - q).squaredNorm());
          sw += w;
          sh += w * h[i];
        }
      }
      if (sw > 0.0) return sh / sw;
    }
    return kNaN;
  }
};

}  // namespace

bool SegmentationImportOptions::is_valid(std::string* error) const {
  if (ures < 8 || ures % 2) {
    *error = "ures must be even and >= 8";
    return false;
  }
  if (vres < 3) {
    *error = "vres must be >= 3";
    return false;
  }
  if (!(pixel_mm > 0.05 && pixel_mm < 5.0)) {
    *error = "pixel_mm must be in (0.05, 5) mm";
    return false;
  }
  const int l[3] = {labels.annulus, labels.anterior, labels.posterior};
  if (l[0] == l[1] || l[0] == l[2] || l[1] == l[2]) {
    *error = "annulus, anterior and posterior labels must differ";
    return false;
  }
  if (l[0] == 0 || l[1] == 0 || l[2] == 0) {
    *error = "label 0 is the background and cannot be a structure";
    return false;
  }
  if (atrial_direction && !(atrial_direction->norm() > 0)) {
    *error = "atrial direction must be a non-zero vector";
    return false;
  }
  return true;
}

SegmentationImport import_segmentation(const ImageVolume& im, const std::string& source,
                                       const SegmentationImportOptions& opt) {
  std::string err;
  if (!opt.is_valid(&err)) throw Error(source + ": " + err);
  if (im.data.size() != im.num_voxels() || im.num_voxels() == 0) {
    throw Error(source + ": label map is empty or its data size does not match its dimensions");
  }
  SegmentationImport out;

  // ---- 1. voxels per label -------------------------------------------------------------------
  std::vector<Voxel> ann, leaf;
  std::vector<int> leaf_label;
  std::map<long, long> histogram;
  for (int k = 0; k < im.size[2]; ++k) {
    for (int j = 0; j < im.size[1]; ++j) {
      for (int i = 0; i < im.size[0]; ++i) {
        const float v = im.at(i, j, k);
        if (!std::isfinite(v)) throw Error(source + ": label map has a NaN/Inf voxel");
        const long l = std::lround(v);
        if (l != 0) ++histogram[l];
        if (l == opt.labels.annulus) ann.push_back({i, j, k, im.position(i, j, k)});
        if (l == opt.labels.anterior || l == opt.labels.posterior) {
          leaf.push_back({i, j, k, im.position(i, j, k)});
          leaf_label.push_back(static_cast<int>(l));
        }
      }
    }
  }
  out.annulus_voxels = static_cast<int>(ann.size());
  out.anterior_voxels =
      static_cast<int>(std::count(leaf_label.begin(), leaf_label.end(), opt.labels.anterior));
  out.posterior_voxels = static_cast<int>(leaf_label.size()) - out.anterior_voxels;
  std::string found;
  for (const auto& [l, n] : histogram)
    found += (found.empty() ? "" : ", ") + std::to_string(l) + ": " + std::to_string(n);
  if (found.empty()) found = "none";
  auto need = [&](int count, int label, const char* what) {
    if (count < 50) {
      throw Error(source + ": label " + std::to_string(label) + " (" + what + ") has " +
                  std::to_string(count) +
                  " voxels, too few to fit (labels found with voxel counts: " + found +
                  "); check the label mapping");
    }
  };
  need(out.annulus_voxels, opt.labels.annulus, "annulus");
  need(out.anterior_voxels, opt.labels.anterior, "anterior leaflet");
  need(out.posterior_voxels, opt.labels.posterior, "posterior leaflet");

  // ---- 2. annulus plane and the atrial side ---------------------------------------------------
  PlaneFrame fr;
  {
    Points P(ann.size(), 3);
    for (size_t i = 0; i < ann.size(); ++i) P.row(i) = ann[i].p.transpose();
    fr.c = P.colwise().mean().transpose();
    const Points C = P.rowwise() - fr.c.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C.transpose() * C);
    fr.n = eig.eigenvectors().col(0);
    fr.e1 = eig.eigenvectors().col(2);
  }
  Eigen::Vector3d leaf_centroid = Eigen::Vector3d::Zero();
  for (const Voxel& v : leaf) leaf_centroid += v.p;
  leaf_centroid /= static_cast<double>(leaf.size());
  if (opt.atrial_direction) {
    if (fr.n.dot(*opt.atrial_direction) < 0) fr.n = -fr.n;
    out.notes.push_back("atrial side: given");
  } else {
    const double tent = fr.n.dot(leaf_centroid - fr.c);
    if (tent > 0) fr.n = -fr.n;
    out.notes.push_back("atrial side: inferred from leaflet tenting (leaflet centroid " +
                        std::to_string(std::abs(tent)) + " mm on the ventricular side)");
  }
  fr.e2 = fr.n.cross(fr.e1);

  // ---- 3. annulus curve: angular bins, then a smooth closed Fourier curve ---------------------
  constexpr int kBins = 90, kDense = 1440;
  std::vector<Eigen::Vector3d> bin_sum(kBins, Eigen::Vector3d::Zero());
  std::vector<int> bin_n(kBins, 0);
  for (const Voxel& v : ann) {
    const Eigen::Vector2d q = fr.to2d(v.p);
    const double a = std::atan2(q.y(), q.x());
    const int b = std::clamp(static_cast<int>((a + pi) / (2 * pi) * kBins), 0, kBins - 1);
    bin_sum[b] += v.p;
    ++bin_n[b];
  }
  std::vector<double> bin_angle, dense_angle(kDense);
  std::vector<double> bx, by, bz;
  for (int b = 0; b < kBins; ++b) {
    if (bin_n[b] == 0) continue;
    const Eigen::Vector3d m = bin_sum[b] / bin_n[b];
    const Eigen::Vector2d q = fr.to2d(m);
    bin_angle.push_back(std::atan2(q.y(), q.x()));
    bx.push_back(m.x());
    by.push_back(m.y());
    bz.push_back(m.z());
  }
  if (bin_angle.size() < kBins / 2) {
    throw Error(source + ": the annulus label covers only " + std::to_string(bin_angle.size()) +
                " of " + std::to_string(kBins) + " angular sectors; it must be a closed ring");
  }
  for (int i = 0; i < kDense; ++i) dense_angle[i] = -pi + 2 * pi * i / kDense;
  const Eigen::VectorXd cx = fourier_fit(bin_angle, bx, 6, dense_angle);
  const Eigen::VectorXd cy = fourier_fit(bin_angle, by, 6, dense_angle);
  const Eigen::VectorXd cz = fourier_fit(bin_angle, bz, 6, dense_angle);
  Points dense(kDense, 3);
  for (int i = 0; i < kDense; ++i) dense.row(i) << cx[i], cy[i], cz[i];

  // ---- 4. commissures: where the leaflet next to the annulus changes from AL to PL ------------
  std::vector<double> score(kDense, 0.0);
  {
    std::vector<double> nal(kDense, 0.0), npl(kDense, 0.0);
    constexpr double kReach = 4.0;  // mm from the annulus curve
    for (size_t i = 0; i < leaf.size(); ++i) {
      const Eigen::Vector2d q = fr.to2d(leaf[i].p);
      const double a = std::atan2(q.y(), q.x());
      const int d = std::clamp(static_cast<int>((a + pi) / (2 * pi) * kDense), 0, kDense - 1);
      if ((dense.row(d).transpose() - leaf[i].p).norm() > kReach + 3.0) continue;
      // distance to the curve near that angle
      double best = 1e30;
      for (int o = -8; o <= 8; ++o) {
        best =
            std::min(best, (dense.row((d + o + kDense) % kDense).transpose() - leaf[i].p).norm());
      }
      if (best > kReach) continue;
      (leaf_label[i] == opt.labels.anterior ? nal : npl)[d] += 1.0;
    }
    constexpr int kWindow = 24;  // +-6 degrees
    for (int i = 0; i < kDense; ++i) {
      double a = 0, p = 0;
      for (int o = -kWindow; o <= kWindow; ++o) {
        a += nal[(i + o + kDense) % kDense];
        p += npl[(i + o + kDense) % kDense];
      }
      score[i] = (a + p) > 0 ? (a - p) / (a + p) : 0.0;
    }
  }
  // Largest circular run of positive score = anterior annulus.
  int best_start = -1, best_len = 0;
  for (int s = 0; s < kDense; ++s) {
    if (score[s] <= 0 || score[(s + kDense - 1) % kDense] > 0) continue;
    int len = 0;
    while (len < kDense && score[(s + len) % kDense] > 0) ++len;
    if (len > best_len) {
      best_len = len;
      best_start = s;
    }
  }
  if (best_start < 0 || best_len >= kDense) {
    throw Error(source +
                ": cannot find the commissures (the anterior and posterior leaflets do "
                "not both touch the annulus)");
  }
  // The plane frame has n into the atrium, so increasing angle is counter-clockwise seen from
  // the atrium; u runs clockwise, entering the anterior arc at its high-angle end.
  const int i_al = (best_start + best_len) % kDense;  // anterolateral commissure
  const int i_pm = best_start;                        // posteromedial commissure
  out.notes.push_back("anterior annulus arc: " + std::to_string(360.0 * best_len / kDense) +
                      " degrees");

  // Sample the annulus on the grid: each arc evenly in arc length, going down in angle.
  const int ures = opt.ures, vres = opt.vres;
  Points annulus(ures, 3);
  auto sample_arc = [&](int from, int count_dense, int u0, int count) {
    std::vector<double> len(count_dense + 1, 0.0);
    for (int s = 1; s <= count_dense; ++s) {
      len[s] = len[s - 1] + (dense.row((from - s + 2 * kDense) % kDense) -
                             dense.row((from - s + 1 + 2 * kDense) % kDense))
                                .norm();
    }
    for (int k = 0; k < count; ++k) {
      const double target = len[count_dense] * k / count;
      const int s =
          static_cast<int>(std::lower_bound(len.begin(), len.end(), target) - len.begin());
      const int s1 = std::max(s, 1);
      const double f = (target - len[s1 - 1]) / std::max(len[s1] - len[s1 - 1], 1e-12);
      const Eigen::Vector3d a = dense.row((from - (s1 - 1) + 2 * kDense) % kDense).transpose();
      const Eigen::Vector3d b = dense.row((from - s1 + 2 * kDense) % kDense).transpose();
      annulus.row(u0 + k) = (a + f * (b - a)).transpose();
    }
  };
  sample_arc(i_al, best_len, 0, ures / 2);
  sample_arc(i_pm, kDense - best_len, ures / 2, ures / 2);

  // ---- 5. atrial height field of the leaflets --------------------------------------------------
  HeightField hf;
  hf.pixel = opt.pixel_mm;
  {
    Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
    for (int i = 0; i < kDense; ++i) {
      const Eigen::Vector2d q = fr.to2d(dense.row(i).transpose());
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    for (const Voxel& v : leaf) {
      const Eigen::Vector2d q = fr.to2d(v.p);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    hf.lo = lo - Eigen::Vector2d::Constant(2.0);
    hf.nx = static_cast<int>(std::ceil((hi.x() - lo.x() + 4.0) / hf.pixel));
    hf.ny = static_cast<int>(std::ceil((hi.y() - lo.y() + 4.0) / hf.pixel));
    hf.h.assign(static_cast<size_t>(hf.nx) * hf.ny, kNaN);
    hf.label.assign(hf.h.size(), 0);
  }
  // Ray-cast every pixel down the atrial normal into the union of leaflet voxels: the entry
  // point is where the voxelized boundary lies, which straddles the true surface without bias.
  const Eigen::Matrix3d axes = im.direction * im.spacing.asDiagonal();
  const Eigen::Matrix3d to_index = axes.inverse();
  std::vector<int> label_of(im.num_voxels(), 0);
  double h_lo = 1e30, h_hi = -1e30;
  for (size_t i = 0; i < leaf.size(); ++i) {
    label_of[leaf[i].i + static_cast<size_t>(im.size[0]) *
                             (leaf[i].j + static_cast<size_t>(im.size[1]) * leaf[i].k)] =
        leaf_label[i];
    h_lo = std::min(h_lo, fr.height(leaf[i].p));
    h_hi = std::max(h_hi, fr.height(leaf[i].p));
  }
  auto label_at = [&](const Eigen::Vector3d& p) -> int {
    const Eigen::Vector3d q = to_index * (p - im.origin);
    const long i = std::lround(q.x()), j = std::lround(q.y()), k = std::lround(q.z());
    if (i < 0 || j < 0 || k < 0 || i >= im.size[0] || j >= im.size[1] || k >= im.size[2]) return 0;
    return label_of[static_cast<size_t>(i) +
                    static_cast<size_t>(im.size[0]) *
                        (static_cast<size_t>(j) +
                         static_cast<size_t>(im.size[1]) * static_cast<size_t>(k))];
  };
  const double step = 0.2 * im.spacing.minCoeff();
  for (int y = 0; y < hf.ny; ++y) {
    for (int x = 0; x < hf.nx; ++x) {
      const Eigen::Vector2d q = hf.centre(x, y);
      double above = h_hi + 2.0 * im.spacing.maxCoeff();
      for (double h = above; h >= h_lo - 2.0 * im.spacing.maxCoeff(); h -= step) {
        const int l = label_at(fr.to3d(q, h));
        if (l == 0) {
          above = h;
          continue;
        }
        double in = h;  // bisect between `above` (outside) and `in` (inside)
        for (int it = 0; it < 8; ++it) {
          const double mid = 0.5 * (above + in);
          (label_at(fr.to3d(q, mid)) ? in : above) = mid;
        }
        hf.h[hf.idx(x, y)] = 0.5 * (above + in);
        hf.label[hf.idx(x, y)] = l;
        break;
      }
    }
  }

  // ---- 6. coaptation line: where the anterior and posterior leaflets meet seen from the atrium
  const Eigen::Vector2d c_al = fr.to2d(annulus.row(0).transpose());
  const Eigen::Vector2d c_pm = fr.to2d(annulus.row(ures / 2).transpose());
  const double span = (c_pm - c_al).norm();
  const Eigen::Vector2d dir = (c_pm - c_al) / span;
  const Eigen::Vector2d perp(-dir.y(), dir.x());
  constexpr int kLineBins = 48;
  std::vector<std::vector<double>> bins(kLineBins);
  for (int y = 0; y + 1 < hf.ny; ++y) {
    for (int x = 0; x + 1 < hf.nx; ++x) {
      const int a = hf.idx(x, y);
      if (std::isnan(hf.h[a])) continue;
      for (const int b : {hf.idx(x + 1, y), hf.idx(x, y + 1)}) {
        if (std::isnan(hf.h[b]) || hf.label[b] == hf.label[a]) continue;
        const Eigen::Vector2d m =
            0.5 * (hf.centre(x, y) + (b == a + 1 ? hf.centre(x + 1, y) : hf.centre(x, y + 1)));
        const double t = dir.dot(m - c_al) / span;
        if (t <= 0.0 || t >= 1.0) continue;
        bins[std::min(static_cast<int>(t * kLineBins), kLineBins - 1)].push_back(
            perp.dot(m - c_al));
      }
    }
  }
  std::vector<double> line_t, line_w;
  for (int b = 0; b < kLineBins; ++b) {
    if (bins[b].size() < 2) continue;
    std::nth_element(bins[b].begin(), bins[b].begin() + bins[b].size() / 2, bins[b].end());
    line_t.push_back((b + 0.5) / kLineBins);
    line_w.push_back(bins[b][bins[b].size() / 2]);
  }
  if (line_t.size() < 6) {
    throw Error(source +
                ": no coaptation line found (the leaflets do not meet seen from the atrium; "
                "is this a closed valve?)");
  }
  // Smooth the line with a low-order polynomial in t.
  const double t_min = line_t.front(), t_max = line_t.back();
  Eigen::VectorXd line_coef;
  {
    constexpr int kDeg = 4;
    Eigen::MatrixXd A(line_t.size(), kDeg + 1);
    Eigen::VectorXd b(line_t.size());
    for (size_t i = 0; i < line_t.size(); ++i) {
      for (int k = 0; k <= kDeg; ++k) A(i, k) = std::pow(line_t[i] - 0.5, k);
      b[i] = line_w[i];
    }
    line_coef = A.colPivHouseholderQr().solve(b);
  }
  auto coaptation = [&](double t) -> Eigen::Vector2d {
    double w = 0.0;
    for (int k = 0; k < line_coef.size(); ++k) w += line_coef[k] * std::pow(t - 0.5, k);
    return c_al + t * span * dir + w * perp;
  };
  out.notes.push_back("coaptation line over " +
                      std::to_string(static_cast<int>(100 * (t_max - t_min))) +
                      " % of the commissural width");

  // ---- 7. the (u,v) grid: straight in the plane from annulus to coaptation line, lifted onto
  //         the atrial height field of the column's own leaflet -----------------------------------
  LeafletGrid::Points P(static_cast<Eigen::Index>(ures) * vres, 3);
  for (int u = 0; u < ures; ++u) {
    const bool anterior = u < ures / 2;
    const double s = anterior ? static_cast<double>(u) / (ures / 2)
                              : static_cast<double>(u - ures / 2) / (ures / 2);
    const double t = anterior ? t_min + s * (t_max - t_min) : t_max - s * (t_max - t_min);
    const Eigen::Vector2d a = fr.to2d(annulus.row(u).transpose());
    const Eigen::Vector2d f = coaptation(t);
    const int own = anterior ? opt.labels.anterior : opt.labels.posterior;
    P.row(u) = annulus.row(u);
    for (int v = 1; v < vres; ++v) {
      const Eigen::Vector2d q = a + (static_cast<double>(v) / (vres - 1)) * (f - a);
      // Commissure columns straddle both leaflets: take whichever is there.
      const bool commissure = (u == 0 || u == ures / 2);
      double h = hf.sample(q, commissure ? -1 : own);
      if (std::isnan(h)) h = hf.sample(q, -1);
      if (std::isnan(h))
        throw Error(source + ": leaflet surface has a hole at grid point (u=" + std::to_string(u) +
                    ", v=" + std::to_string(v) + ")");
      P.row(static_cast<Eigen::Index>(v) * ures + u) = fr.to3d(q, h).transpose();
    }
  }
  LeafletGrid grid(ures, vres, std::move(P));

  // ---- 8. the patient -------------------------------------------------------------------------
  Patient& pt = out.patient;
  pt.id = std::filesystem::path(source).filename().string();
  pt.synthetic = false;
  pt.provenance.version = kVersion;
  pt.provenance.created_utc = utc_now_iso8601();
  pt.provenance.source = "segmentation import: " + source +
                         " (labels annulus=" + std::to_string(opt.labels.annulus) +
                         " anterior=" + std::to_string(opt.labels.anterior) +
                         " posterior=" + std::to_string(opt.labels.posterior) + ")";
  ValveSequence& seq = pt.sequence;
  seq.ures = ures;
  seq.vres = vres;
  seq.end_diastole = -1;
  seq.first_closed = 0;
  ValveFrame frame;
  frame.time_s = 0.0;
  frame.annulus = annulus;
  for (int l = 0; l < kNumLandmarks; ++l) {
    frame.landmarks[l].setConstant(kNaN);
    frame.landmark_observed[l] = false;
  }
  auto set = [&](Landmark l, const Eigen::Vector3d& x) {
    frame.landmarks[index(l)] = x;
    frame.landmark_observed[index(l)] = true;
  };
  set(Landmark::kAnterolateralCommissure, annulus.row(0).transpose());
  set(Landmark::kPosteromedialCommissure, annulus.row(ures / 2).transpose());
  set(Landmark::kPosteriorAnnulusMidpoint, grid.sample(0.75, 0.0));
  set(Landmark::kAnteriorLeafletTip, grid.sample(0.25, 1.0));
  set(Landmark::kPosteriorLeafletTip, grid.sample(0.75, 1.0));
  frame.la_surface = grid;
  seq.frames.push_back(std::move(frame));
  if (opt.keep_label_map) pt.images.push_back(im);
  seq.validate(source.c_str());

  // ---- 9. fit quality -------------------------------------------------------------------------
  // The leaflet mask boundary as a surface of voxel faces.
  {
    std::vector<std::uint8_t> is_leaf(im.num_voxels(), 0);
    for (const Voxel& v : leaf)
      is_leaf[v.i +
              static_cast<size_t>(im.size[0]) * (v.j + static_cast<size_t>(im.size[1]) * v.k)] = 1;
    auto leaf_at = [&](int i, int j, int k) {
      if (i < 0 || j < 0 || k < 0 || i >= im.size[0] || j >= im.size[1] || k >= im.size[2])
        return false;
      return is_leaf[i + static_cast<size_t>(im.size[0]) *
                             (j + static_cast<size_t>(im.size[1]) * k)] != 0;
    };
    TriangleMesh faces;
    std::vector<Eigen::Vector3d> V;
    std::vector<Eigen::Vector3i> F;
    std::vector<Eigen::Vector3d> atrial_centres;
    const int off[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (const Voxel& v : leaf) {
      for (const auto& o : off) {
        if (leaf_at(v.i + o[0], v.j + o[1], v.k + o[2])) continue;
        const int ax = o[0] ? 0 : (o[1] ? 1 : 2);
        const double sgn = o[0] + o[1] + o[2];
        const Eigen::Vector3d normal = sgn * im.direction.col(ax);
        const Eigen::Vector3d centre = v.p + 0.5 * sgn * axes.col(ax);
        const Eigen::Vector3d ea = 0.5 * axes.col((ax + 1) % 3), eb = 0.5 * axes.col((ax + 2) % 3);
        const int base = static_cast<int>(V.size());
        V.push_back(centre - ea - eb);
        V.push_back(centre + ea - eb);
        V.push_back(centre + ea + eb);
        V.push_back(centre - ea + eb);
        F.emplace_back(base, base + 1, base + 2);
        F.emplace_back(base, base + 2, base + 3);
        if (normal.dot(fr.n) > 0.3) atrial_centres.push_back(centre);
      }
    }
    faces.V.resize(static_cast<Eigen::Index>(V.size()), 3);
    faces.F.resize(static_cast<Eigen::Index>(F.size()), 3);
    for (size_t i = 0; i < V.size(); ++i)
      faces.V.row(static_cast<Eigen::Index>(i)) = V[i].transpose();
    for (size_t i = 0; i < F.size(); ++i)
      faces.F.row(static_cast<Eigen::Index>(i)) = F[i].transpose();
    out.surface_to_mask = point_to_mesh_distance(grid.points(), faces);
    Points ac(static_cast<Eigen::Index>(atrial_centres.size()), 3);
    for (size_t i = 0; i < atrial_centres.size(); ++i)
      ac.row(static_cast<Eigen::Index>(i)) = atrial_centres[i].transpose();
    out.mask_to_surface = point_to_mesh_distance(ac, grid.triangulate());
  }
  {
    std::vector<double> d;
    for (int i = 0; i < kDense; i += 4) {
      double best = 1e30;
      for (const Voxel& v : ann)
        best = std::min(best, (v.p - dense.row(i).transpose()).squaredNorm());
      d.push_back(std::sqrt(best));
    }
    out.annulus_to_mask = distance_stats(std::move(d));
  }
  return out;
}

}  // namespace mvtwin
