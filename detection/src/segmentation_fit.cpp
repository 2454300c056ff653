#include "mvtwin/detection/segmentation_fit.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>

#include <Eigen/Dense>

#include "mvtwin/core/error.h"
#include "mvtwin/core/nan.h"
#include "mvtwin/core/triangle_bvh.h"

namespace mvtwin::detection {
namespace {

using std::numbers::pi;
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
constexpr int kDense = 1440;  // samples of the dense annulus curve (0.25 degree)

// Codes of the working label volume.
enum Code : std::uint8_t { kNone = 0, kAnt = 1, kPost = 2, kRing = 3, kPap = 4 };

struct Voxel {
  int i, j, k;
  Eigen::Vector3d p;
  std::uint8_t code;
};

/// Orthonormal frame of the annulus: origin at its centre, n into the atrium.
struct PlaneFrame {
  Eigen::Vector3d c, e1, e2, n;
  Eigen::Vector2d to2d(const Eigen::Vector3d& p) const { return {e1.dot(p - c), e2.dot(p - c)}; }
  double height(const Eigen::Vector3d& p) const { return n.dot(p - c); }
  double angle(const Eigen::Vector3d& p) const {
    const Eigen::Vector2d q = to2d(p);
    return std::atan2(q.y(), q.x());
  }
  void complete() {
    e2 = n.cross(e1).normalized();
    e1 = e2.cross(n);
  }
};

int dense_bin(double angle) {
  return std::clamp(static_cast<int>((angle + pi) / (2 * pi) * kDense), 0, kDense - 1);
}

/// Least-squares Fourier series of order `order` through (angle, value), at kDense angles.
Eigen::VectorXd fourier_fit(const std::vector<double>& angle, const std::vector<double>& value,
                            int order) {
  const int m = 2 * order + 1;
  auto row = [&](double a, auto&& r) {
    r(0) = 1.0;
    for (int k = 1; k <= order; ++k) {
      r(2 * k - 1) = std::cos(k * a);
      r(2 * k) = std::sin(k * a);
    }
  };
  Eigen::MatrixXd A(angle.size(), m);
  Eigen::VectorXd b(angle.size());
  for (size_t i = 0; i < angle.size(); ++i) {
    row(angle[i], A.row(static_cast<Eigen::Index>(i)));
    b[static_cast<Eigen::Index>(i)] = value[i];
  }
  const Eigen::VectorXd coef = A.colPivHouseholderQr().solve(b);
  Eigen::VectorXd out(kDense);
  Eigen::RowVectorXd r(m);
  for (int i = 0; i < kDense; ++i) {
    row(-pi + 2 * pi * i / kDense, r);
    out[i] = r.dot(coef);
  }
  return out;
}

/// A smooth closed curve (kDense points, point i at angle -pi + 2 pi i / kDense) through points
/// given with their angles.
Points closed_curve(const std::vector<double>& angle, const std::vector<Eigen::Vector3d>& p,
                    int order) {
  std::vector<double> x(p.size()), y(p.size()), z(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    x[i] = p[i].x();
    y[i] = p[i].y();
    z[i] = p[i].z();
  }
  const Eigen::VectorXd cx = fourier_fit(angle, x, order), cy = fourier_fit(angle, y, order),
                        cz = fourier_fit(angle, z, order);
  Points d(kDense, 3);
  for (int i = 0; i < kDense; ++i) d.row(i) << cx[i], cy[i], cz[i];
  return d;
}

PlaneFrame pca_frame(const std::vector<Eigen::Vector3d>& pts) {
  PlaneFrame fr;
  Points P(static_cast<Eigen::Index>(pts.size()), 3);
  for (size_t i = 0; i < pts.size(); ++i) P.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
  fr.c = P.colwise().mean().transpose();
  const Points C = P.rowwise() - fr.c.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(C.transpose() * C);
  fr.n = eig.eigenvectors().col(0);
  fr.e1 = eig.eigenvectors().col(2);
  fr.complete();
  return fr;
}

/// 26-connected components of the voxels whose code is `c` in a volume of `n` voxels per axis
/// (x fastest): each voxel's component (-1 elsewhere) and each component's voxel count.
struct Components {
  std::vector<int> id;
  std::vector<long> size;
};

Components components(const std::vector<std::uint8_t>& code, std::uint8_t c,
                      const std::array<int, 3>& n) {
  const long nx = n[0], ny = n[1], nz = n[2];
  Components out;
  out.id.assign(code.size(), -1);
  std::vector<std::size_t> stack;
  for (std::size_t v = 0; v < code.size(); ++v) {
    if (code[v] != c || out.id[v] >= 0) continue;
    const int id = static_cast<int>(out.size.size());
    long count = 0;
    stack.push_back(v);
    out.id[v] = id;
    while (!stack.empty()) {
      const std::size_t w = stack.back();
      stack.pop_back();
      ++count;
      const long i = static_cast<long>(w) % nx, j = (static_cast<long>(w) / nx) % ny,
                 k = static_cast<long>(w) / (nx * ny);
      for (long dk = -1; dk <= 1; ++dk)
        for (long dj = -1; dj <= 1; ++dj)
          for (long di = -1; di <= 1; ++di) {
            const long a = i + di, b = j + dj, e = k + dk;
            if (a < 0 || b < 0 || e < 0 || a >= nx || b >= ny || e >= nz) continue;
            const std::size_t q = static_cast<std::size_t>(a + nx * (b + ny * e));
            if (code[q] == c && out.id[q] < 0) {
              out.id[q] = id;
              stack.push_back(q);
            }
          }
    }
    out.size.push_back(count);
  }
  return out;
}

/// The landmarks the grid itself carries (docs/valve-model.md): commissures, posterior annulus
/// mid-point and leaflet tips, marked observed.
void set_grid_landmarks(const LeafletGrid& g, ValveFrame* f) {
  auto set = [&](Landmark l, const Eigen::Vector3d& x) {
    f->landmarks[index(l)] = x;
    f->landmark_observed[index(l)] = true;
  };
  set(Landmark::kAnterolateralCommissure, g.at(0, 0));
  set(Landmark::kPosteromedialCommissure, g.at(g.ures() / 2, 0));
  set(Landmark::kPosteriorAnnulusMidpoint, g.sample(0.75, 0.0));
  set(Landmark::kAnteriorLeafletTip, g.sample(0.25, 1.0));
  set(Landmark::kPosteriorLeafletTip, g.sample(0.75, 1.0));
}

/// The faces of `m` that `keep` selects, with only the vertices they use.
TriangleMesh face_subset(const TriangleMesh& m, const std::vector<bool>& keep) {
  std::vector<int> id(static_cast<size_t>(m.V.rows()), -1);
  std::vector<Eigen::Vector3d> V;
  std::vector<Eigen::Vector3i> F;
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    if (!keep[static_cast<size_t>(f)]) continue;
    Eigen::Vector3i t;
    for (int k = 0; k < 3; ++k) {
      int& x = id[static_cast<size_t>(m.F(f, k))];
      if (x < 0) {
        x = static_cast<int>(V.size());
        V.push_back(m.V.row(m.F(f, k)).transpose());
      }
      t[k] = x;
    }
    F.push_back(t);
  }
  TriangleMesh out;
  out.V.resize(static_cast<Eigen::Index>(V.size()), 3);
  for (size_t i = 0; i < V.size(); ++i) out.V.row(static_cast<Eigen::Index>(i)) = V[i].transpose();
  out.F.resize(static_cast<Eigen::Index>(F.size()), 3);
  for (size_t i = 0; i < F.size(); ++i) out.F.row(static_cast<Eigen::Index>(i)) = F[i].transpose();
  return out;
}

}  // namespace

bool SegmentationFitOptions::is_valid(std::string* error) const {
  if (!labels.is_valid(error)) return false;
  if (ures < 8 || ures % 2) {
    *error = "ures must be even and >= 8";
    return false;
  }
  if (vres < 3) {
    *error = "vres must be >= 3";
    return false;
  }
  if (atrial_direction && !(atrial_direction->norm() > 0 && atrial_direction->allFinite())) {
    *error = "the atrial direction must be a finite, non-zero vector";
    return false;
  }
  if (!(max_secondary_component > 0 && max_secondary_component <= 1)) {
    *error = "max_secondary_component must be in (0, 1]";
    return false;
  }
  return true;
}

FrameFit fit_segmentation_frame(const ImageVolume& im, const std::string& source,
                                const SegmentationFitOptions& opt) {
  std::string err;
  if (!opt.is_valid(&err)) throw Error(source + ": " + err);
  if (im.data.size() != im.num_voxels() || im.num_voxels() == 0)
    throw Error(source + ": label map is empty or its data size does not match its dimensions");
  if (!im.spacing.allFinite() || !(im.spacing.minCoeff() > 0) || !im.direction.allFinite() ||
      !im.origin.allFinite() || std::abs(im.direction.determinant()) < 1e-6)
    throw Error(source + ": label map has an invalid geometry (spacing, origin or axes)");
  FrameFit out;
  out.source = source;
  const SegmentationLabels& L = opt.labels;
  const std::size_t nx = im.size[0], ny = im.size[1], nz = im.size[2];
  auto lin = [&](long i, long j, long k) {
    return static_cast<std::size_t>(i) + nx * (j + ny * static_cast<std::size_t>(k));
  };

  // ---- 1. codes per voxel ---------------------------------------------------------------------
  std::vector<std::uint8_t> code(im.num_voxels(), kNone);
  std::map<long, long> histogram;
  for (std::size_t v = 0; v < im.num_voxels(); ++v) {
    const float x = im.data[v];
    if (!std::isfinite(x)) throw Error(source + ": label map has a NaN/Inf voxel");
    const long l = std::lround(x);
    if (l == 0) continue;
    ++histogram[l];
    if (l == L.anterior)
      code[v] = kAnt;
    else if (l == L.posterior)
      code[v] = kPost;
    else if (L.annulus && l == L.annulus)
      code[v] = kRing;
    else if (L.papillary && l == L.papillary)
      code[v] = kPap;
  }
  std::string found;
  for (const auto& [l, n] : histogram)
    found += (found.empty() ? "" : ", ") + std::to_string(l) + ": " + std::to_string(n);
  if (found.empty()) found = "none";
  auto count_of = [&](int l) { return histogram.count(l) ? histogram[l] : 0L; };
  auto need = [&](int label, const char* what) {
    if (count_of(label) < 50) {
      throw Error(source + ": label " + std::to_string(label) + " (" + what + ") has " +
                  std::to_string(count_of(label)) +
                  " voxels, too few to fit (labels found with voxel counts: " + found +
                  "); check the label convention (--convention) or the values (--labels)");
    }
  };
  if (histogram.empty())
    throw Error(source + ": no valve found: the label map is empty (every voxel is 0)");
  need(L.anterior, "anterior leaflet");
  need(L.posterior, "posterior leaflet");

  // ---- 2. connected components of each leaflet label (26-neighbourhood) -----------------------
  for (std::uint8_t c : {kAnt, kPost}) {
    const Components cc = components(code, c, im.size);
    const std::vector<long>& sizes = cc.size;
    const std::vector<int>& comp = cc.id;
    const int big = static_cast<int>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
    const char* what = c == kAnt ? "anterior leaflet" : "posterior leaflet";
    const int value = c == kAnt ? L.anterior : L.posterior;
    long dropped = 0;
    int dropped_n = 0;
    for (size_t s = 0; s < sizes.size(); ++s) {
      if (static_cast<int>(s) == big) continue;
      if (sizes[s] >= opt.max_secondary_component * sizes[big] && sizes[s] >= 50) {
        throw Error(source + ": label " + std::to_string(value) + " (" + what +
                    ") has several disconnected components (" + std::to_string(sizes[big]) +
                    " and " + std::to_string(sizes[s]) +
                    " voxels, ...); a leaflet must be one piece (clean the segmentation, or check "
                    "the label values)");
      }
      dropped += sizes[s];
      ++dropped_n;
    }
    if (dropped_n > 0) {
      for (std::size_t v = 0; v < im.num_voxels(); ++v)
        if (code[v] == c && comp[v] != big) code[v] = kNone;
      out.notes.push_back(std::string(what) + ": dropped " + std::to_string(dropped_n) +
                          " small detached piece(s), " + std::to_string(dropped) + " voxels");
    }
  }

  // ---- 3. voxel lists, border check ----------------------------------------------------------
  std::vector<Voxel> leaf, ring, pap;
  for (std::size_t k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const std::uint8_t c = code[lin(i, j, k)];
        if (c == kNone) continue;
        Voxel v{static_cast<int>(i), static_cast<int>(j), static_cast<int>(k), im.position(i, j, k),
                c};
        if (c == kAnt || c == kPost) {
          if (i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz) {
            throw Error(
                source + ": the leaflets touch the image border at voxel (" + std::to_string(i) +
                ", " + std::to_string(j) + ", " + std::to_string(k) +
                "): the valve is cut off by the field of view, so its shape cannot be fitted");
          }
          leaf.push_back(v);
        } else if (c == kRing) {
          ring.push_back(v);
        } else {
          pap.push_back(v);
        }
      }
  for (const Voxel& v : leaf) (v.code == kAnt ? out.anterior_voxels : out.posterior_voxels)++;
  out.annulus_voxels = static_cast<int>(ring.size());
  out.papillary_voxels = static_cast<int>(pap.size());
  const double voxel = im.spacing.maxCoeff();
  const bool use_ring = L.annulus != 0 && opt.use_annulus_label && ring.size() >= 50;
  if (L.annulus != 0 && ring.size() < 50) {
    out.notes.push_back("annulus label " + std::to_string(L.annulus) + " has " +
                        std::to_string(ring.size()) +
                        " voxels: the annulus is taken from the leaflet rim");
  }

  // ---- 4. plane, atrial side, and the annulus curve(s) ----------------------------------------
  std::vector<Eigen::Vector3d> leaf_p;
  for (const Voxel& v : leaf) leaf_p.push_back(v.p);
  Eigen::Vector3d leaf_centroid = Eigen::Vector3d::Zero();
  for (const auto& p : leaf_p) leaf_centroid += p;
  leaf_centroid /= static_cast<double>(leaf_p.size());

  // The leaflets lie on the ventricular side of the annulus (hanging open or tenting closed).
  auto orient = [&](PlaneFrame* fr) {
    if (opt.atrial_direction) {
      if (fr->n.dot(*opt.atrial_direction) < 0) fr->n = -fr->n;
    } else if (fr->n.dot(leaf_centroid - fr->c) > 0) {
      fr->n = -fr->n;
    }
    fr->complete();
  };

  // The rim of the leaflets: per angular sector, the voxels furthest out and up (score r + 2h;
  // the attachment is the outermost point of the atrial surface, open or closed).
  auto rim_points = [&](const PlaneFrame& fr, std::vector<double>* angle,
                        std::vector<Eigen::Vector3d>* pts) {
    constexpr int kBins = 72;
    std::vector<std::vector<std::pair<double, Eigen::Vector3d>>> bins(kBins);
    for (const auto& p : leaf_p) {
      const Eigen::Vector2d q = fr.to2d(p);
      const int b = std::clamp(static_cast<int>((std::atan2(q.y(), q.x()) + pi) / (2 * pi) * kBins),
                               0, kBins - 1);
      bins[b].emplace_back(q.norm() + 2.0 * fr.height(p), p);
    }
    angle->clear();
    pts->clear();
    for (auto& b : bins) {
      if (b.size() < 3) continue;
      std::partial_sort(b.begin(), b.begin() + 3, b.end(),
                        [](const auto& x, const auto& y) { return x.first > y.first; });
      // Voxel centres sit half a voxel inside the boundary: move out along the score direction.
      Eigen::Vector3d m = (b[0].second + b[1].second + b[2].second) / 3.0;
      const Eigen::Vector2d q = fr.to2d(m);
      const Eigen::Vector3d out_dir = (q.x() * fr.e1 + q.y() * fr.e2).normalized();
      m += 0.5 * voxel * (out_dir + 2.0 * fr.n) / std::sqrt(5.0);
      angle->push_back(fr.angle(m));
      pts->push_back(m);
    }
  };

  PlaneFrame fr;
  Points dense_ring, dense_rim;
  if (use_ring) {
    std::vector<Eigen::Vector3d> rp;
    for (const Voxel& v : ring) rp.push_back(v.p);
    fr = pca_frame(rp);
    orient(&fr);
    constexpr int kBins = 90;
    std::vector<Eigen::Vector3d> sum(kBins, Eigen::Vector3d::Zero());
    std::vector<int> cnt(kBins, 0);
    for (const auto& p : rp) {
      const int b =
          std::clamp(static_cast<int>((fr.angle(p) + pi) / (2 * pi) * kBins), 0, kBins - 1);
      sum[b] += p;
      ++cnt[b];
    }
    std::vector<double> ang;
    std::vector<Eigen::Vector3d> pts;
    for (int b = 0; b < kBins; ++b) {
      if (!cnt[b]) continue;
      pts.push_back(sum[b] / cnt[b]);
      ang.push_back(fr.angle(pts.back()));
    }
    if (ang.size() < kBins / 2) {
      throw Error(source + ": the annulus label covers only " + std::to_string(ang.size()) +
                  " of " + std::to_string(kBins) +
                  " angular sectors; it must be a closed ring (or leave it out: --labels without "
                  "an annulus value)");
    }
    dense_ring = closed_curve(ang, pts, 6);
    out.annulus_source = "annulus label";
    out.notes.push_back(
        opt.atrial_direction
            ? "atrial side: given"
            : "atrial side: the leaflets lie on the ventricular side of the annulus label");
  }
  {
    // The rim: iterate plane and rim points from a start frame.
    auto converge = [&](PlaneFrame rf, std::vector<double>* ang,
                        std::vector<Eigen::Vector3d>* pts) {
      for (int it = 0; it < 4; ++it) {
        rim_points(rf, ang, pts);
        if (pts->size() < 36)
          throw Error(source + ": no leaflet rim found (the leaflets do not surround an orifice)");
        PlaneFrame next = pca_frame(*pts);
        if (next.n.dot(rf.n) < 0) next.n = -next.n;
        next.complete();
        rf = next;
      }
      rim_points(rf, ang, pts);
      double r = 0;
      for (const auto& p : *pts) r += rf.to2d(p).norm();
      return std::make_pair(rf, r / static_cast<double>(pts->size()));
    };
    std::vector<double> ang;
    std::vector<Eigen::Vector3d> pts;
    if (use_ring) {
      rim_points(fr, &ang, &pts);
      if (pts.size() < 36)
        throw Error(source + ": no leaflet rim found (the leaflets do not surround an orifice)");
    } else {
      // Without an annulus label the atrial side is the one whose rim is widest: the
      // attachment is the widest part of the leaflets, open (a funnel) or closed (a tent that
      // may billow inside the annulus); the rim found from the other side is the free edge
      // or the coaptation zone.
      PlaneFrame start = pca_frame(leaf_p);
      if (opt.atrial_direction) orient(&start);
      auto [f1, r1] = converge(start, &ang, &pts);
      if (!opt.atrial_direction) {
        PlaneFrame flipped = start;
        flipped.n = -flipped.n;
        flipped.complete();
        std::vector<double> ang2;
        std::vector<Eigen::Vector3d> pts2;
        auto [f2, r2] = converge(flipped, &ang2, &pts2);
        if (r2 > r1) {
          f1 = f2;
          ang = ang2;
          pts = pts2;
        }
      }
      fr = f1;
      out.annulus_source = "leaflet rim";
      out.notes.push_back(opt.atrial_direction
                              ? "atrial side: given"
                              : "atrial side: the side on which the leaflets' rim is widest");
    }
    for (size_t i = 0; i < pts.size(); ++i) ang[i] = fr.angle(pts[i]);
    dense_rim = closed_curve(ang, pts, 6);
  }
  const Points& dense = use_ring ? dense_ring : dense_rim;

  // ---- 5. commissures: where the leaflet next to the annulus changes from AL to PL ------------
  std::vector<double> score(kDense, 0.0);
  {
    std::vector<double> nal(kDense, 0.0), npl(kDense, 0.0);
    constexpr double kReach = 4.0;  // mm from the annulus curve
    for (const Voxel& v : leaf) {
      const int d = dense_bin(fr.angle(v.p));
      double best = 1e30;
      for (int o = -8; o <= 8; ++o)
        best = std::min(best, (dense.row((d + o + kDense) % kDense).transpose() - v.p).norm());
      if (best > kReach) continue;
      (v.code == kAnt ? nal : npl)[d] += 1.0;
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
                ": cannot find the commissures (the anterior and posterior leaflets do not both "
                "reach the annulus)");
  }
  // n points into the atrium, so increasing angle is counter-clockwise seen from the atrium; u
  // runs clockwise, entering the anterior arc at its high-angle end.
  const int i_al = (best_start + best_len) % kDense, i_pm = best_start;
  const double anterior_arc_deg = 360.0 * best_len / kDense;
  out.notes.push_back("anterior annulus arc: " +
                      std::to_string(static_cast<int>(std::lround(anterior_arc_deg))) + " degrees");
  // Swapped labels: the anterior leaflet hangs from about a third of the annulus (the
  // aortic-mitral curtain between the trigones), the posterior from the rest. Voxel counts do
  // not tell them apart (the two leaflets' areas are similar). Warned, never swapped silently.
  if (anterior_arc_deg > 180.0) {
    out.warnings.push_back(
        "the anterior leaflet label (" + std::to_string(L.anterior) + ", " +
        std::to_string(out.anterior_voxels) + " voxels) hangs from " +
        std::to_string(static_cast<int>(std::lround(anterior_arc_deg))) +
        " degrees of the annulus, the posterior one (" + std::to_string(L.posterior) + ", " +
        std::to_string(out.posterior_voxels) +
        " voxels) from the rest; the anterior leaflet normally takes about a third: are the "
        "labels swapped?");
  }
  const int ures = opt.ures, vres = opt.vres;
  auto sample_annulus = [&](const Points& curve, std::vector<int>* dense_index) {
    Points a(ures, 3);
    dense_index->assign(ures, 0);
    auto arc = [&](int from, int count_dense, int u0, int count) {
      std::vector<double> len(count_dense + 1, 0.0);
      for (int s = 1; s <= count_dense; ++s)
        len[s] = len[s - 1] + (curve.row((from - s + 2 * kDense) % kDense) -
                               curve.row((from - s + 1 + 2 * kDense) % kDense))
                                  .norm();
      for (int k = 0; k < count; ++k) {
        const double target = len[count_dense] * k / count;
        const int s =
            static_cast<int>(std::lower_bound(len.begin(), len.end(), target) - len.begin());
        const int s1 = std::max(s, 1);
        const double f = (target - len[s1 - 1]) / std::max(len[s1] - len[s1 - 1], 1e-12);
        const Eigen::Vector3d pa = curve.row((from - (s1 - 1) + 2 * kDense) % kDense).transpose();
        const Eigen::Vector3d pb = curve.row((from - s1 + 2 * kDense) % kDense).transpose();
        a.row(u0 + k) = (pa + f * (pb - pa)).transpose();
        (*dense_index)[u0 + k] = (from - (s1 - 1) + 2 * kDense) % kDense;
      }
    };
    arc(i_al, best_len, 0, ures / 2);
    arc(i_pm, kDense - best_len, ures / 2, ures / 2);
    return a;
  };
  std::vector<int> annulus_dense_index;
  const Points annulus = sample_annulus(dense, &annulus_dense_index);
  if (use_ring) {
    // The rim at the label annulus's angles, for the comparison.
    out.rim_annulus.resize(ures, 3);
    std::vector<double> d;
    for (int u = 0; u < ures; ++u) {
      out.rim_annulus.row(u) = dense_rim.row(annulus_dense_index[u]);
      d.push_back((out.rim_annulus.row(u) - annulus.row(u)).norm());
    }
    out.rim_vs_label = distance_stats(d);
    std::vector<double> dv;
    for (int u = 0; u < ures; ++u) {
      double best = 1e30;
      for (const Voxel& v : ring)
        best = std::min(best, (v.p - out.rim_annulus.row(u).transpose()).squaredNorm());
      dv.push_back(std::sqrt(best));
    }
    out.rim_to_label_voxels = distance_stats(dv);
  }

  // ---- 6. leaflet columns: in the plane through each annulus point across the annulus, follow
  //         the atrial boundary of the column's leaflet outwards from the annulus -----------------
  const Eigen::Matrix3d axes = im.direction * im.spacing.asDiagonal();
  const Eigen::Matrix3d to_index = axes.inverse();
  auto code_at = [&](const Eigen::Vector3d& p) -> std::uint8_t {
    const Eigen::Vector3d q = to_index * (p - im.origin);
    const long i = std::lround(q.x()), j = std::lround(q.y()), k = std::lround(q.z());
    if (i < 0 || j < 0 || k < 0 || i >= static_cast<long>(nx) || j >= static_cast<long>(ny) ||
        k >= static_cast<long>(nz))
      return kNone;
    return code[lin(i, j, k)];
  };
  const double vmin = im.spacing.minCoeff();
  const double dr = std::min(0.25, 0.5 * vmin);
  // Traces column u; `any_leaflet` accepts either leaflet label (always at the commissures).
  // Returns the column's vres points, or nothing when the leaflet cannot be followed.
  auto trace = [&](int u, bool any_leaflet) -> std::optional<std::vector<Eigen::Vector3d>> {
    const Eigen::Vector3d a = annulus.row(u).transpose();
    Eigen::Vector3d d =
        (annulus.row((u + 1) % ures) - annulus.row((u + ures - 1) % ures)).transpose().cross(fr.n);
    d -= d.dot(fr.n) * fr.n;
    d.normalize();
    const std::uint8_t own = u < ures / 2 ? kAnt : kPost;
    auto inside = [&](double r, double th) {
      const std::uint8_t c = code_at(a + r * (std::cos(th) * d + std::sin(th) * fr.n));
      return any_leaflet ? (c == kAnt || c == kPost) : c == own;
    };
    std::vector<double> rs, ths;
    double miss = 0.0;
    for (double r = 0.5; r < 70.0; r += dr) {
      const double dth = 0.25 * vmin / r;
      double hi, lo;
      if (ths.empty()) {
        hi = 100.0 * pi / 180;
        lo = -150.0 * pi / 180;
      } else {
        // Wider after a miss, so that a gap or a sharp turn does not lose the leaflet.
        const double widen = 1.0 + miss;
        hi = ths.back() + widen * std::max(20.0 * pi / 180, std::atan(3.0 / r));
        lo = ths.back() - widen * std::max(45.0 * pi / 180, std::atan(6.0 / r));
      }
      // Start outside the leaflet, above it.
      double th = hi;
      while (inside(r, th) && th < hi + pi / 2) th += dth;
      bool hit = false;
      if (!inside(r, th)) {
        for (double t = th; t >= lo; t -= dth) {
          if (inside(r, t)) {
            double out_t = t + dth, in_t = t;
            for (int it = 0; it < 8; ++it) {
              const double mid = 0.5 * (out_t + in_t);
              (inside(r, mid) ? in_t : out_t) = mid;
            }
            rs.push_back(r);
            ths.push_back(0.5 * (out_t + in_t));
            hit = true;
            break;
          }
        }
      }
      if (hit) {
        miss = 0.0;
      } else if (!ths.empty()) {
        miss += dr;
        if (miss > 2.0) {
          // A track shorter than 4 mm was a false start (the hinge, a speck): start again.
          if (rs.back() - rs.front() < 4.0 && r < 10.0) {
            rs.clear();
            ths.clear();
            miss = 0.0;
            continue;
          }
          break;
        }
      } else if (r > 10.0) {
        break;
      }
    }
    if (rs.size() < 4 || rs.back() - rs.front() < 1.0) return std::nullopt;
    // Smooth the angle along the column: running median of 5, then mean of 5.
    std::vector<double> med(ths.size()), sm(ths.size());
    for (size_t i = 0; i < ths.size(); ++i) {
      std::vector<double> w;
      for (long o = -2; o <= 2; ++o) {
        const long j = static_cast<long>(i) + o;
        if (j >= 0 && j < static_cast<long>(ths.size())) w.push_back(ths[static_cast<size_t>(j)]);
      }
      std::nth_element(w.begin(), w.begin() + static_cast<long>(w.size() / 2), w.end());
      med[i] = w[w.size() / 2];
    }
    for (size_t i = 0; i < ths.size(); ++i) {
      double sum = 0;
      int n = 0;
      for (long o = -2; o <= 2; ++o) {
        const long j = static_cast<long>(i) + o;
        if (j >= 0 && j < static_cast<long>(ths.size())) {
          sum += med[static_cast<size_t>(j)];
          ++n;
        }
      }
      sm[i] = sum / n;
    }
    std::vector<Eigen::Vector3d> curve = {a};
    for (size_t i = 0; i < rs.size(); ++i)
      curve.push_back(a + rs[i] * (std::cos(sm[i]) * d + std::sin(sm[i]) * fr.n));
    std::vector<double> len(curve.size(), 0.0);
    for (size_t i = 1; i < curve.size(); ++i)
      len[i] = len[i - 1] + (curve[i] - curve[i - 1]).norm();
    std::vector<Eigen::Vector3d> column(static_cast<size_t>(vres));
    for (int v = 0; v < vres; ++v) {
      const double target = len.back() * v / (vres - 1);
      size_t i =
          static_cast<size_t>(std::lower_bound(len.begin(), len.end(), target) - len.begin());
      i = std::clamp<size_t>(i, 1, len.size() - 1);
      const double f = (target - len[i - 1]) / std::max(len[i] - len[i - 1], 1e-12);
      column[static_cast<size_t>(v)] =
          curve[i - 1] + std::clamp(f, 0.0, 1.0) * (curve[i] - curve[i - 1]);
    }
    return column;
  };
  std::vector<std::optional<std::vector<Eigen::Vector3d>>> columns(static_cast<size_t>(ures));
  std::vector<int> relaxed, missing;
  for (int u = 0; u < ures; ++u) {
    const bool commissure = u == 0 || u == ures / 2;
    columns[static_cast<size_t>(u)] = trace(u, commissure);
    if (!columns[static_cast<size_t>(u)] && !commissure) {
      columns[static_cast<size_t>(u)] = trace(u, true);
      if (columns[static_cast<size_t>(u)]) relaxed.push_back(u);
    }
    if (!columns[static_cast<size_t>(u)]) missing.push_back(u);
  }
  auto list = [](const std::vector<int>& v) {
    std::string s;
    for (int x : v) s += (s.empty() ? "" : ", ") + std::to_string(x);
    return s;
  };
  if (!relaxed.empty()) {
    out.notes.push_back(
        "grid columns u = " + list(relaxed) +
        ": the column's own leaflet could not be followed, the other leaflet's label was accepted");
  }
  if (static_cast<int>(missing.size()) * 5 > ures) {
    throw Error(source + ": the leaflets cannot be followed from the annulus at grid columns u = " +
                list(missing) +
                " (no leaflet within 10 mm of the annulus there, or a gap in the segmentation)");
  }
  if (!missing.empty()) {
    out.warnings.push_back("grid columns u = " + list(missing) +
                           ": no leaflet could be followed from the annulus; interpolated from the "
                           "neighbouring columns");
  }
  LeafletGrid::Points P(static_cast<Eigen::Index>(ures) * vres, 3);
  for (int u = 0; u < ures; ++u) {
    if (columns[static_cast<size_t>(u)]) {
      for (int v = 0; v < vres; ++v)
        P.row(static_cast<Eigen::Index>(v) * ures + u) =
            (*columns[static_cast<size_t>(u)])[static_cast<size_t>(v)].transpose();
      continue;
    }
    int l = u, r = u, dl = 0, dr2 = 0;
    while (!columns[static_cast<size_t>(l)]) {
      l = (l + ures - 1) % ures;
      ++dl;
    }
    while (!columns[static_cast<size_t>(r)]) {
      r = (r + 1) % ures;
      ++dr2;
    }
    const double w = static_cast<double>(dl) / (dl + dr2);
    for (int v = 0; v < vres; ++v) {
      const Eigen::Vector3d pl =
          (*columns[static_cast<size_t>(l)])[static_cast<size_t>(v)] - annulus.row(l).transpose();
      const Eigen::Vector3d pr =
          (*columns[static_cast<size_t>(r)])[static_cast<size_t>(v)] - annulus.row(r).transpose();
      P.row(static_cast<Eigen::Index>(v) * ures + u) =
          (annulus.row(u).transpose() + (1 - w) * pl + w * pr).transpose();
    }
  }
  LeafletGrid grid(ures, vres, std::move(P));

  // ---- 7. the frame -------------------------------------------------------------------------
  ValveFrame& frame = out.frame;
  frame.time_s = 0.0;
  frame.annulus = annulus;
  for (int l = 0; l < kNumLandmarks; ++l) {
    frame.landmarks[l].setConstant(kNaN);
    frame.landmark_observed[l] = false;
  }
  set_grid_landmarks(grid, &frame);
  frame.la_surface = grid;
  auto set = [&](Landmark l, const Eigen::Vector3d& x) {
    frame.landmarks[index(l)] = x;
    frame.landmark_observed[index(l)] = true;
  };

  // Papillary tips from a papillary label: the atrial-most point of each of the two largest
  // pieces; the one nearer the anterolateral commissure is the anterolateral tip.
  if (L.papillary != 0 && !pap.empty()) {
    const Components cc = components(code, kPap, im.size);
    std::vector<std::vector<int>> pieces(cc.size.size());
    for (size_t i = 0; i < pap.size(); ++i)
      pieces[static_cast<size_t>(cc.id[lin(pap[i].i, pap[i].j, pap[i].k)])].push_back(
          static_cast<int>(i));
    std::sort(pieces.begin(), pieces.end(),
              [](const auto& x, const auto& y) { return x.size() > y.size(); });
    if (pieces.size() < 2 || pieces[1].size() < 10) {
      out.warnings.push_back("papillary label " + std::to_string(L.papillary) +
                             ": fewer than two papillary muscles found; tips not taken from it");
    } else {
      Eigen::Vector3d tip[2];
      for (int m = 0; m < 2; ++m) {
        double top = -1e300;
        for (int w : pieces[m]) top = std::max(top, fr.height(pap[w].p));
        Eigen::Vector3d s = Eigen::Vector3d::Zero();
        int n = 0;
        for (int w : pieces[m]) {
          if (fr.height(pap[w].p) >= top - 0.5 * voxel) {
            s += pap[w].p;
            ++n;
          }
        }
        tip[m] = s / n + 0.5 * voxel * fr.n;  // voxel centres lie half a voxel inside
      }
      const Eigen::Vector3d al = annulus.row(0).transpose(), pm = annulus.row(ures / 2).transpose();
      const bool swap =
          (tip[0] - al).norm() - (tip[0] - pm).norm() > (tip[1] - al).norm() - (tip[1] - pm).norm();
      set(Landmark::kAnterolateralPapillaryTip, tip[swap ? 1 : 0]);
      set(Landmark::kPosteromedialPapillaryTip, tip[swap ? 0 : 1]);
      out.notes.push_back("papillary tips: from label " + std::to_string(L.papillary));
    }
  }

  // ---- 8. fit quality ----------------------------------------------------------------------
  {
    auto is_leaf = [&](long i, long j, long k) {
      if (i < 0 || j < 0 || k < 0 || i >= static_cast<long>(nx) || j >= static_cast<long>(ny) ||
          k >= static_cast<long>(nz))
        return false;
      const std::uint8_t c = code[lin(i, j, k)];
      return c == kAnt || c == kPost;
    };
    TriangleMesh faces;
    std::vector<Eigen::Vector3d> V, centres, normals;
    std::vector<Eigen::Vector3i> F;
    const int off[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (const Voxel& v : leaf) {
      for (const auto& o : off) {
        if (is_leaf(v.i + o[0], v.j + o[1], v.k + o[2])) continue;
        const int ax = o[0] ? 0 : (o[1] ? 1 : 2);
        const double sgn = o[0] + o[1] + o[2];
        const Eigen::Vector3d c = v.p + 0.5 * sgn * axes.col(ax);
        const Eigen::Vector3d ea = 0.5 * axes.col((ax + 1) % 3), eb = 0.5 * axes.col((ax + 2) % 3);
        const int base = static_cast<int>(V.size());
        V.push_back(c - ea - eb);
        V.push_back(c + ea - eb);
        V.push_back(c + ea + eb);
        V.push_back(c - ea + eb);
        F.emplace_back(base, base + 1, base + 2);
        F.emplace_back(base, base + 2, base + 3);
        centres.push_back(c);
        normals.push_back(sgn * im.direction.col(ax));
      }
    }
    faces.V.resize(static_cast<Eigen::Index>(V.size()), 3);
    faces.F.resize(static_cast<Eigen::Index>(F.size()), 3);
    for (size_t i = 0; i < V.size(); ++i)
      faces.V.row(static_cast<Eigen::Index>(i)) = V[i].transpose();
    for (size_t i = 0; i < F.size(); ++i)
      faces.F.row(static_cast<Eigen::Index>(i)) = F[i].transpose();
    out.surface_to_mask = point_to_mesh_distance(grid.points(), faces);
    // Atrial-facing faces: facing against the fitted surface's ventricular normal nearby.
    const TriangleMesh tri = grid.triangulate();
    Points vn = Points::Zero(tri.V.rows(), 3);
    for (Eigen::Index f = 0; f < tri.F.rows(); ++f) {
      const Eigen::Vector3d p0 = tri.V.row(tri.F(f, 0)), p1 = tri.V.row(tri.F(f, 1)),
                            p2 = tri.V.row(tri.F(f, 2));
      const Eigen::Vector3d w = (p1 - p0).cross(p2 - p0);
      for (int k = 0; k < 3; ++k) vn.row(tri.F(f, k)) += w.transpose();
    }
    for (Eigen::Index i = 0; i < vn.rows(); ++i) vn.row(i).normalize();
    std::vector<Eigen::Vector3d> atrial;
    for (size_t f = 0; f < centres.size(); ++f) {
      Eigen::Index best = 0;
      (tri.V.rowwise() - centres[f].transpose()).rowwise().squaredNorm().minCoeff(&best);
      if (normals[f].dot(-vn.row(best).transpose()) > 0.3) atrial.push_back(centres[f]);
    }
    Points ac(static_cast<Eigen::Index>(atrial.size()), 3);
    for (size_t i = 0; i < atrial.size(); ++i)
      ac.row(static_cast<Eigen::Index>(i)) = atrial[i].transpose();
    if (ac.rows() > 0) out.mask_to_surface = point_to_mesh_distance(ac, tri);
  }
  if (use_ring) {
    std::vector<double> d;
    for (int i = 0; i < kDense; i += 4) {
      double best = 1e30;
      for (const Voxel& v : ring)
        best = std::min(best, (v.p - dense.row(i).transpose()).squaredNorm());
      d.push_back(std::sqrt(best));
    }
    out.annulus_to_label = distance_stats(std::move(d));
  }
  // Orifice: pixels of the annulus plane inside the annulus that no leaflet voxel covers.
  {
    const double pix = std::max(0.5, 0.7 * voxel);
    Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
    std::vector<Eigen::Vector2d> poly;
    for (int i = 0; i < kDense; i += 4) {
      poly.push_back(fr.to2d(dense.row(i).transpose()));
      lo = lo.cwiseMin(poly.back());
      hi = hi.cwiseMax(poly.back());
    }
    const int gx = static_cast<int>((hi.x() - lo.x()) / pix) + 1,
              gy = static_cast<int>((hi.y() - lo.y()) / pix) + 1;
    std::vector<std::uint8_t> cover(static_cast<std::size_t>(gx) * gy, 0);
    const int reach = static_cast<int>(std::ceil(0.6 * voxel / pix));
    for (const Voxel& v : leaf) {
      const Eigen::Vector2d q = fr.to2d(v.p);
      const int cx = static_cast<int>((q.x() - lo.x()) / pix),
                cy = static_cast<int>((q.y() - lo.y()) / pix);
      for (int y = cy - reach; y <= cy + reach; ++y)
        for (int x = cx - reach; x <= cx + reach; ++x)
          if (x >= 0 && y >= 0 && x < gx && y < gy) cover[static_cast<std::size_t>(x) + gx * y] = 1;
    }
    long open = 0;
    for (int y = 0; y < gy; ++y)
      for (int x = 0; x < gx; ++x) {
        if (cover[static_cast<std::size_t>(x) + gx * y]) continue;
        const Eigen::Vector2d q = lo + pix * Eigen::Vector2d(x + 0.5, y + 0.5);
        bool in = false;  // even-odd rule
        for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
          if ((poly[i].y() > q.y()) != (poly[j].y() > q.y()) &&
              q.x() < (poly[j].x() - poly[i].x()) * (q.y() - poly[i].y()) /
                              (poly[j].y() - poly[i].y()) +
                          poly[i].x())
            in = !in;
        }
        open += in;
      }
    out.orifice_area_mm2 = open * pix * pix;
  }
  return out;
}

std::pair<TriangleMesh, TriangleMesh> leaflet_surface_meshes(const LeafletGrid& grid, int ures,
                                                             int vres) {
  const LeafletGrid fine = grid.resampled(ures, vres);
  const TriangleMesh all = fine.triangulate();
  const Eigen::VectorXi tags = fine.triangle_tags();
  std::vector<bool> anterior(static_cast<size_t>(all.F.rows())), posterior(anterior.size());
  for (Eigen::Index t = 0; t < all.F.rows(); ++t) {
    anterior[static_cast<size_t>(t)] = tags[t] == static_cast<int>(LeafletTag::kAnterior);
    posterior[static_cast<size_t>(t)] = !anterior[static_cast<size_t>(t)];
  }
  return {face_subset(all, anterior), face_subset(all, posterior)};
}

std::pair<TriangleMesh, TriangleMesh> split_leaflet_meshes(const TriangleMesh& m,
                                                           const std::string& source) {
  m.check(source.c_str());
  // Union-find over vertices joined by triangles.
  std::vector<int> parent(static_cast<size_t>(m.V.rows()));
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<int>(i);
  auto find = [&](int x) {
    while (parent[static_cast<size_t>(x)] != x)
      x = parent[static_cast<size_t>(x)] =
          parent[static_cast<size_t>(parent[static_cast<size_t>(x)])];
    return x;
  };
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    for (int k = 1; k < 3; ++k) parent[static_cast<size_t>(find(m.F(f, k)))] = find(m.F(f, 0));
  std::map<int, double> area;
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    area[find(m.F(f, 0))] += 0.5 * (b - a).cross(c - a).norm();
  }
  std::vector<std::pair<double, int>> by_area;
  for (const auto& [root, a] : area) by_area.emplace_back(a, root);
  std::sort(by_area.rbegin(), by_area.rend());
  if (by_area.size() < 2 || by_area[1].first < 0.05 * by_area[0].first) {
    throw Error(
        source +
        ": the surface is one connected piece; give the anterior and posterior leaflets as two "
        "files (--mesh anterior.stl,posterior.stl) or as two separate pieces of one file");
  }
  auto piece = [&](int root) {
    std::vector<bool> keep(static_cast<size_t>(m.F.rows()));
    for (Eigen::Index f = 0; f < m.F.rows(); ++f)
      keep[static_cast<size_t>(f)] = find(m.F(f, 0)) == root;
    return face_subset(m, keep);
  };
  // Which is anterior: the anterior leaflet is a tall shield on a third of the annulus, the
  // posterior a long low crescent on the rest (Mansi et al. 2012, Sec. 2.1), so the anterior
  // piece is the rounder one in the isoperimetric sense: the larger area / boundary length^2.
  auto roundness = [](const TriangleMesh& t) {
    std::map<std::pair<int, int>, int> uses;
    double surface = 0;
    for (Eigen::Index f = 0; f < t.F.rows(); ++f) {
      const Eigen::Vector3d a = t.V.row(t.F(f, 0)), b = t.V.row(t.F(f, 1)), c = t.V.row(t.F(f, 2));
      surface += 0.5 * (b - a).cross(c - a).norm();
      for (int k = 0; k < 3; ++k) {
        const int i = t.F(f, k), j = t.F(f, (k + 1) % 3);
        ++uses[{std::min(i, j), std::max(i, j)}];
      }
    }
    double boundary = 0;
    for (const auto& [e, n] : uses)
      if (n == 1) boundary += (t.V.row(e.first) - t.V.row(e.second)).norm();
    return surface / std::max(boundary * boundary, 1e-300);
  };
  TriangleMesh a = piece(by_area[0].second), b = piece(by_area[1].second);
  if (roundness(b) > roundness(a)) std::swap(a, b);
  return {a, b};
}

FrameFit fit_surface_frame(const TriangleMesh& anterior, const TriangleMesh& posterior,
                           const std::string& source, const SegmentationFitOptions& options,
                           double voxel_mm) {
  anterior.check((source + " (anterior leaflet)").c_str());
  posterior.check((source + " (posterior leaflet)").c_str());
  if (anterior.F.rows() == 0 || posterior.F.rows() == 0)
    throw Error(source + ": a leaflet mesh has no triangles");
  if (!(voxel_mm >= 0.1 && voxel_mm <= 2.0))
    throw Error(source + ": the rasterizing voxel must be in [0.1, 2] mm");
  constexpr double kHalfThickness = 0.65;  // mm: half the FE model's leaflet thickness
  const double reach = kHalfThickness;
  Eigen::Vector3d lo = anterior.V.colwise().minCoeff().transpose().cwiseMin(
      posterior.V.colwise().minCoeff().transpose());
  Eigen::Vector3d hi = anterior.V.colwise().maxCoeff().transpose().cwiseMax(
      posterior.V.colwise().maxCoeff().transpose());
  lo -= Eigen::Vector3d::Constant(reach + 3 * voxel_mm);
  hi += Eigen::Vector3d::Constant(reach + 3 * voxel_mm);
  ImageVolume im;
  im.spacing = Eigen::Vector3d::Constant(voxel_mm);
  im.origin = lo;
  for (int k = 0; k < 3; ++k) {
    im.size[k] = static_cast<int>(std::ceil((hi[k] - lo[k]) / voxel_mm)) + 1;
    if (im.size[k] > 1500)
      throw Error(source + ": the leaflet meshes span more than 600 mm: wrong units?");
  }
  im.data.assign(im.num_voxels(), 0.0f);
  std::vector<float> best(im.num_voxels(), static_cast<float>(reach));
  const TriangleMesh* meshes[2] = {&anterior, &posterior};
  for (int leaf = 0; leaf < 2; ++leaf) {
    const TriangleMesh& m = *meshes[leaf];
    const TriangleBvh bvh(m);
    std::vector<std::uint8_t> near(im.num_voxels(), 0);
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
      Eigen::Vector3d a = m.V.row(m.F(f, 0)).transpose(), b = a;
      for (int k = 1; k < 3; ++k) {
        a = a.cwiseMin(m.V.row(m.F(f, k)).transpose());
        b = b.cwiseMax(m.V.row(m.F(f, k)).transpose());
      }
      const Eigen::Vector3d i0 = (a - lo).array() / voxel_mm - reach / voxel_mm,
                            i1 = (b - lo).array() / voxel_mm + reach / voxel_mm;
      for (int z = std::max(0, static_cast<int>(std::floor(i0.z())));
           z <= std::min(im.size[2] - 1, static_cast<int>(std::ceil(i1.z()))); ++z)
        for (int y = std::max(0, static_cast<int>(std::floor(i0.y())));
             y <= std::min(im.size[1] - 1, static_cast<int>(std::ceil(i1.y()))); ++y)
          for (int x = std::max(0, static_cast<int>(std::floor(i0.x())));
               x <= std::min(im.size[0] - 1, static_cast<int>(std::ceil(i1.x()))); ++x)
            near[static_cast<size_t>(x) +
                 static_cast<size_t>(im.size[0]) *
                     (static_cast<size_t>(y) +
                      static_cast<size_t>(im.size[1]) * static_cast<size_t>(z))] = 1;
    }
    for (int z = 0; z < im.size[2]; ++z)
      for (int y = 0; y < im.size[1]; ++y)
        for (int x = 0; x < im.size[0]; ++x) {
          const size_t v = static_cast<size_t>(x) +
                           static_cast<size_t>(im.size[0]) *
                               (static_cast<size_t>(y) +
                                static_cast<size_t>(im.size[1]) * static_cast<size_t>(z));
          if (!near[v]) continue;
          const double d = bvh.closest(im.position(x, y, z)).distance;
          if (d <= static_cast<double>(best[v])) {
            best[v] = static_cast<float>(d);
            im.data[v] = leaf == 0 ? 2.0f : 3.0f;
          }
        }
  }
  SegmentationFitOptions o = options;
  o.labels = {2, 3, 0, 0, "surface meshes"};
  FrameFit fit = fit_segmentation_frame(im, source, o);
  fit.annulus_source = "leaflet mesh rim";
  // Onto the meshes: every grid point to the closest point of its own leaflet's mesh (either at
  // the commissures), the annulus row to the meshes' rim.
  const TriangleBvh ba(anterior), bp(posterior);
  LeafletGrid& g = *fit.frame.la_surface;
  const int U = g.ures();
  for (int v = 0; v < g.vres(); ++v)
    for (int u = 0; u < U; ++u) {
      const Eigen::Vector3d p = g.at(u, v);
      const TriangleBvh::Hit ha = ba.closest(p), hp = bp.closest(p);
      const bool commissure = u == 0 || u == U / 2;
      const TriangleBvh::Hit& h =
          commissure ? (ha.distance < hp.distance ? ha : hp) : (u < U / 2 ? ha : hp);
      g.points().row(static_cast<Eigen::Index>(v) * U + u) = h.point.transpose();
    }
  fit.frame.annulus = g.points().topRows(U);
  set_grid_landmarks(g, &fit.frame);
  // Fit quality against the meshes themselves.
  TriangleMesh both;
  both.V.resize(anterior.V.rows() + posterior.V.rows(), 3);
  both.V << anterior.V, posterior.V;
  both.F.resize(anterior.F.rows() + posterior.F.rows(), 3);
  both.F << anterior.F, (posterior.F.array() + static_cast<int>(anterior.V.rows())).matrix();
  fit.surface_to_mask = point_to_mesh_distance(g.points(), both);
  fit.mask_to_surface = point_to_mesh_distance(both.V, g.triangulate());
  fit.notes.push_back("surface meshes rasterized at " + std::to_string(voxel_mm).substr(0, 4) +
                      " mm, fitted, and the grid moved onto the meshes; fit errors are to the "
                      "meshes (all of their vertices)");
  return fit;
}

}  // namespace mvtwin::detection
