#include "mvtwin/detection/tee_renderer.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <memory>
#include <numbers>

#include <Eigen/Geometry>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/core/triangle_bvh.h"

namespace mvtwin::detection {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// A valve-centred frame of one time frame: centre and mean radius of the annulus, atrial
/// normal n, anterior direction a, anterolateral direction l = n x a.
struct ValveAxes {
  Eigen::Vector3d c, n, a, l;
  double radius = 0;
};

ValveAxes valve_axes(const ValveFrame& f) {
  ValveAxes v;
  v.c = f.annulus.colwise().mean().transpose();
  v.n = annulus_plane(f).normal;
  Eigen::Vector3d ant;
  if (f.observed(Landmark::kAnterolateralTrigone) && f.observed(Landmark::kPosteromedialTrigone)) {
    ant = 0.5 * (f.landmark(Landmark::kAnterolateralTrigone) +
                 f.landmark(Landmark::kPosteromedialTrigone));
  } else {
    ant = f.annulus.row(f.annulus.rows() / 4).transpose();  // u = 1/4: the anterior annulus
  }
  v.a = (ant - v.c) - v.n * v.n.dot(ant - v.c);
  if (!(v.a.norm() > 1e-9)) throw Error("synthetic TEE: the annulus has no anterior direction");
  v.a.normalize();
  v.l = v.n.cross(v.a);
  for (int i = 0; i < f.annulus.rows(); ++i)
    v.radius += (f.annulus.row(i).transpose() - v.c).norm();
  v.radius /= static_cast<double>(f.annulus.rows());
  return v;
}

double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                        const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (p - a - t * ab).norm();
}

/// A band of half-width w around a surface at signed distance s: 1 inside, smooth edges.
double band(double s, double w) {
  const double x = std::abs(s) / w;
  return x >= 1.5 ? 0.0 : x <= 0.5 ? 1.0 : 0.5 * (1.0 + std::cos(std::numbers::pi * (x - 0.5)));
}

/// The backscatter (relative intensity) of one frame's anatomy.
class Scene {
 public:
  Scene(const ValveFrame& f, double blood)
      : axes_(valve_axes(f)), blood_(blood), annulus_(f.annulus) {
    if (f.la_surface) {
      mesh_ = f.la_surface->triangulate();
      bvh_ = std::make_unique<TriangleBvh>(mesh_);
      lo_ = mesh_.V.colwise().minCoeff().transpose().array() - 2.0;
      hi_ = mesh_.V.colwise().maxCoeff().transpose().array() + 2.0;
    }
    const ValveAxes& v = axes_;
    for (int k = 0; k < 2; ++k) {
      const Landmark tip =
          k == 0 ? Landmark::kAnterolateralPapillaryTip : Landmark::kPosteromedialPapillaryTip;
      if (f.observed(tip)) papillary_.push_back(f.landmark(tip));
    }
    aorta_base_ = v.c + (v.radius + 9.0) * v.a - 4.0 * v.n;
    aorta_dir_ = (v.n + 0.45 * v.a).normalized();
  }

  double operator()(const Eigen::Vector3d& q, const Eigen::Vector3d& beam) const {
    const ValveAxes& v = axes_;
    const Eigen::Vector3d d = q - v.c;
    const double z = v.n.dot(d), x = v.a.dot(d), y = v.l.dot(d);
    const double rho = std::sqrt(x * x + y * y), R = v.radius;
    double e = blood_;
    // Left-ventricular myocardium: an ellipsoidal shell below the annulus, 10 mm thick.
    if (z < 2.0) {
      const double rlv = 1.12 * R, len = 85.0;
      const double s = std::sqrt((rho / rlv) * (rho / rlv) + (z / len) * (z / len)) - 1.0;
      e = std::max(e, 0.02 * band(s * rlv - 5.0, 5.0));
    }
    // Left-atrial wall: a thinner shell above the annulus.
    if (z > -2.0) {
      const double rla = 1.25 * R, h = 1.6 * R;
      const double s = std::sqrt((rho / rla) * (rho / rla) + (z / h) * (z / h)) - 1.0;
      e = std::max(e, 0.01 * band(s * rla - 1.5, 1.5));
    }
    // Fibrous annulus ring.
    if (std::abs(z) < 8.0 && std::abs(rho - R) < 8.0) {
      double dmin = 1e9;
      for (int i = 0; i < annulus_.rows(); ++i)
        dmin =
            std::min(dmin, segment_distance(q, annulus_.row(i).transpose(),
                                            annulus_.row((i + 1) % annulus_.rows()).transpose()));
      e = std::max(e, 0.08 * band(dmin, 2.0));
    }
    // Aortic root: a tube anterior to the anterior leaflet.
    {
      const Eigen::Vector3d w = q - aorta_base_;
      const double along = w.dot(aorta_dir_);
      if (along > -6.0 && along < 45.0) {
        const double r = (w - along * aorta_dir_).norm();
        e = std::max(e, 0.05 * band(r - 12.0, 1.4));
      }
    }
    // Papillary muscles: capsules from each tip towards the apex.
    for (const Eigen::Vector3d& tip : papillary_) {
      const double dm = segment_distance(q, tip, tip - 22.0 * v.n + 0.0 * v.a);
      e = std::max(e, 0.03 * band(dm - 3.0, 3.0));
    }
    // Leaflets: thin and bright, brightest face on to the beam (specular).
    if (bvh_ && (q.array() >= lo_.array()).all() && (q.array() <= hi_.array()).all()) {
      const TriangleBvh::Hit h = bvh_->closest(q);
      if (h.distance < 1.6) {
        const auto F = mesh_.F.row(h.triangle);
        const Eigen::Vector3d nt = (mesh_.V.row(F[1]) - mesh_.V.row(F[0]))
                                       .cross(mesh_.V.row(F[2]) - mesh_.V.row(F[0]))
                                       .transpose()
                                       .normalized();
        const double facing = std::abs(nt.dot(beam));
        e = std::max(e, (0.25 + 0.75 * facing) * band(h.distance, 0.65));
      }
    }
    return e;
  }

 private:
  ValveAxes axes_;
  double blood_;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> annulus_;
  TriangleMesh mesh_;
  std::unique_ptr<TriangleBvh> bvh_;
  Eigen::Vector3d lo_, hi_;
  std::vector<Eigen::Vector3d> papillary_;
  Eigen::Vector3d aorta_base_, aorta_dir_;
};

std::vector<double> gaussian_kernel(double sigma) {
  const int h = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<double> k(2 * h + 1);
  double s = 0;
  for (int i = -h; i <= h; ++i)
    s += k[i + h] = std::exp(-0.5 * i * i / std::max(sigma * sigma, 1e-6));
  for (double& x : k) x /= s;
  return k;
}

/// Separable blur of a (n0 fastest, n1, n2) array along one axis, zero outside.
template <typename T>
void blur_axis(std::vector<T>* a, const std::array<int, 3>& n, int axis,
               const std::vector<double>& k) {
  const int h = static_cast<int>(k.size() / 2);
  const std::array<std::size_t, 3> stride = {1, static_cast<std::size_t>(n[0]),
                                             static_cast<std::size_t>(n[0]) * n[1]};
  std::vector<T> line(static_cast<std::size_t>(n[axis])), out(line.size());
  const int o1 = axis == 0 ? 1 : 0, o2 = axis == 2 ? 1 : 2;
  for (int j = 0; j < n[o2]; ++j) {
    for (int i = 0; i < n[o1]; ++i) {
      const std::size_t base = i * stride[o1] + j * stride[o2];
      for (int t = 0; t < n[axis]; ++t) line[t] = (*a)[base + t * stride[axis]];
      for (int t = 0; t < n[axis]; ++t) {
        T s{};
        for (int m = -h; m <= h; ++m) {
          const int u = t + m;
          if (u >= 0 && u < n[axis]) s += line[u] * k[m + h];
        }
        out[t] = s;
      }
      for (int t = 0; t < n[axis]; ++t) (*a)[base + t * stride[axis]] = out[t];
    }
  }
}

}  // namespace

std::string TeeRenderOptions::invalid() const {
  if (!(voxel_mm >= 0.3 && voxel_mm <= 3.0)) return "voxel_mm must be in [0.3, 3] mm";
  if (!(box_mm >= 20 && box_mm <= 200)) return "box_mm must be in [20, 200] mm";
  if (!(sector_deg >= 20 && sector_deg <= 110)) return "sector_deg must be in [20, 110] degrees";
  if (!(probe_depth_mm >= 30 && probe_depth_mm <= 200))
    return "probe_depth_mm must be in [30, 200] mm";
  if (!(probe_jitter_deg >= 0 && probe_jitter_deg <= 30))
    return "probe_jitter_deg must be in [0, 30]";
  if (!(axial_psf_mm > 0 && lateral_psf_mm > 0 && axial_psf_mm < 10 && lateral_psf_mm < 10))
    return "PSF widths must be in (0, 10) mm";
  if (!(attenuation_db_per_mm >= 0 && attenuation_db_per_mm < 2))
    return "attenuation must be in [0, 2) dB/mm";
  if (!(dynamic_range_db >= 10 && dynamic_range_db <= 100))
    return "dynamic range must be in [10, 100] dB";
  if (!(speckle >= 0 && speckle <= 1)) return "speckle must be in [0, 1]";
  if (!(noise >= 0 && noise < 10)) return "noise must be in [0, 10)";
  if (!(dropout_fraction >= 0 && dropout_fraction < 1)) return "dropout_fraction must be in [0, 1)";
  if (!(blood >= 0 && blood < 1)) return "blood must be in [0, 1)";
  return "";
}

TeeGeometry tee_geometry(const ValveSequence& seq, const TeeRenderOptions& o) {
  if (const std::string e = o.invalid(); !e.empty()) throw Error("synthetic TEE: " + e);
  if (seq.frames.empty()) throw Error("synthetic TEE: the sequence has no frames");
  const ValveFrame& ref = seq.frames[std::max(0, seq.end_diastole)];
  const ValveAxes v = valve_axes(ref);
  TeeGeometry g;
  // Mid-oesophageal view: the probe behind the left atrium, posterior and above the valve.
  Eigen::Vector3d to_probe = (0.88 * v.n - 0.47 * v.a).normalized();
  double depth = o.probe_depth_mm;
  Eigen::Vector3d centre = v.c;
  double spin = 0;
  if (o.probe_jitter_deg > 0) {
    Rng rng(o.seed ^ 0x9e3779b97f4a7c15ull);
    const double j = o.probe_jitter_deg * kDeg;
    const Eigen::Vector3d tilt_axis =
        to_probe.cross(Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal())).normalized();
    to_probe = Eigen::AngleAxisd(rng.uniform(-j, j), tilt_axis) * to_probe;
    spin = rng.uniform(-2 * j, 2 * j);
    depth += rng.uniform(-8, 8);
    centre += Eigen::Vector3d(rng.uniform(-6, 6), rng.uniform(-6, 6), rng.uniform(-6, 6));
  }
  g.apex = v.c + depth * to_probe;
  const Eigen::Vector3d axis = -to_probe;
  const Eigen::Vector3d lateral =
      Eigen::AngleAxisd(spin, axis) * (v.l - axis * axis.dot(v.l)).normalized();
  g.axes.col(0) = lateral;
  g.axes.col(1) = axis.cross(lateral);
  g.axes.col(2) = axis;
  const int n = std::max(2, static_cast<int>(std::lround(o.box_mm / o.voxel_mm)));
  g.grid.size = {n, n, n};
  g.grid.spacing = Eigen::Vector3d::Constant(o.voxel_mm);
  g.grid.direction = g.axes;
  const double half = 0.5 * (n - 1) * o.voxel_mm;
  g.grid.origin = centre - g.axes * Eigen::Vector3d(half, half, half);
  return g;
}

ImageVolume render_tee_frame(const ValveSequence& seq, int frame, const TeeGeometry& g,
                             const TeeRenderOptions& o) {
  if (frame < 0 || frame >= seq.num_frames())
    throw Error("synthetic TEE: frame " + std::to_string(frame) + " is out of range");
  const ValveFrame& f = seq.frames[static_cast<std::size_t>(frame)];
  const Scene scene(f, o.blood);
  Rng rng(o.seed * 1000003ull + static_cast<std::uint64_t>(frame));

  // Beam space: range r (fastest), lateral angle, elevation angle.
  const double mid = 0.5 * (g.grid.size[0] - 1);
  const double D = (g.grid.position(mid, mid, mid) - g.apex).norm();  // apex to the cube's centre
  const double half_box = 0.5 * std::sqrt(3.0) * o.box_mm;
  // The ranges that cross the cube: from the apex's distance to it to its farthest corner.
  const double edge = (g.grid.size[0] - 1) * o.voxel_mm;
  const Eigen::Vector3d apex_local = g.axes.transpose() * (g.apex - g.grid.origin);
  const double r0 =
      std::max(2.0, (apex_local - apex_local.cwiseMax(0.0).cwiseMin(edge)).norm() - 3.0);
  const double r1 = std::min(D + half_box, r0 + 2 * half_box + 6.0);
  const double dr = std::min(0.5, o.axial_psf_mm);
  const double dth = 0.8 * o.lateral_psf_mm / D;  // rad: lateral samples finer than the PSF
  // Only the beams that cross the output cube are formed.
  double half_angle = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d v =
        g.axes.transpose() *
        (g.grid.position((c & 1) * (g.grid.size[0] - 1), ((c >> 1) & 1) * (g.grid.size[1] - 1),
                         ((c >> 2) & 1) * (g.grid.size[2] - 1)) -
         g.apex);
    half_angle = v.z() <= 1e-6 ? 10.0
                               : std::max({half_angle, std::abs(std::atan(v.x() / v.z())),
                                           std::abs(std::atan(v.y() / v.z()))});
    if (half_angle >= 10.0) break;
  }
  half_angle = std::min(0.5 * o.sector_deg * kDeg, half_angle + 2 * dth);
  const std::array<int, 3> n = {static_cast<int>((r1 - r0) / dr) + 1,
                                2 * static_cast<int>(half_angle / dth) + 1,
                                2 * static_cast<int>(half_angle / dth) + 1};
  const double th0 = -dth * (n[1] / 2);
  auto ray = [&](int i1, int i2) {
    const double tx = std::tan(th0 + i1 * dth), ty = std::tan(th0 + i2 * dth);
    return (g.axes * Eigen::Vector3d(tx, ty, 1.0)).normalized();
  };
  const std::size_t total = static_cast<std::size_t>(n[0]) * n[1] * n[2];
  std::vector<double> coherent(total);
  std::vector<std::complex<double>> speck(total);
  // Only the part of each ray that crosses the output box is sampled.
  const Eigen::Vector3d box_lo = g.grid.origin;
  const double box_len = (g.grid.size[0] - 1) * o.voxel_mm;
  for (int i2 = 0; i2 < n[2]; ++i2) {
    for (int i1 = 0; i1 < n[1]; ++i1) {
      const Eigen::Vector3d b = ray(i1, i2);
      const std::size_t base =
          static_cast<std::size_t>(n[0]) * (i1 + static_cast<std::size_t>(n[1]) * i2);
      for (int i0 = 0; i0 < n[0]; ++i0) {
        const Eigen::Vector3d q = g.apex + (r0 + i0 * dr) * b;
        const Eigen::Vector3d local = g.axes.transpose() * (q - box_lo);
        const double margin = 3.0;
        double amp = 0.0;
        if ((local.array() > -margin).all() && (local.array() < box_len + margin).all())
          amp = std::sqrt(scene(q, b));
        coherent[base + i0] = (1.0 - o.speckle) * amp;
        const double g1 = rng.normal(), g2 = rng.normal();
        speck[base + i0] = o.speckle * amp * std::complex<double>(g1, g2) * std::sqrt(0.5);
      }
    }
  }
  // Point-spread function: Gaussian along the beam and across it (constant in angle, so its
  // width in mm grows with depth as a focused beam's does beyond the focus).
  const auto ka = gaussian_kernel(o.axial_psf_mm / dr);
  const auto kl = gaussian_kernel(o.lateral_psf_mm / (D * dth));
  double norm = 0;  // keeps the mean speckle power of a uniform region at its backscatter
  {
    double sa = 0, sl = 0;
    for (double w : ka) sa += w * w;
    for (double w : kl) sl += w * w;
    norm = 1.0 / std::sqrt(sa * sl * sl);
  }
  for (int axis = 0; axis < 3; ++axis) {
    blur_axis(&coherent, n, axis, axis == 0 ? ka : kl);
    blur_axis(&speck, n, axis, axis == 0 ? ka : kl);
  }
  // Drop-outs: smooth random patches of beams with little signal.
  std::vector<double> gain(static_cast<std::size_t>(n[1]) * n[2], 1.0);
  if (o.dropout_fraction > 0) {
    std::vector<double> field(gain.size());
    for (double& x : field) x = rng.normal();
    const std::array<int, 3> m = {n[1], n[2], 1};
    const auto ks = gaussian_kernel(std::max(2.0, 0.06 * n[1]));
    blur_axis(&field, m, 0, ks);
    blur_axis(&field, m, 1, ks);
    std::vector<double> sorted = field;
    const auto k =
        static_cast<std::ptrdiff_t>(o.dropout_fraction * static_cast<double>(sorted.size()));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    const double threshold = sorted[static_cast<std::size_t>(k)];
    double sd = 0;
    for (double x : field) sd += x * x;
    sd = std::sqrt(sd / static_cast<double>(field.size()));
    for (std::size_t i = 0; i < gain.size(); ++i) {
      const double t = std::clamp((field[i] - threshold) / (0.3 * sd) + 0.5, 0.0, 1.0);
      gain[i] = 0.1 + 0.9 * t;
    }
  }
  // Envelope, attenuation, noise, log compression.
  std::vector<double> attenuation(static_cast<std::size_t>(n[0]));
  for (int i0 = 0; i0 < n[0]; ++i0)
    attenuation[static_cast<std::size_t>(i0)] =
        std::pow(10.0, -o.attenuation_db_per_mm * (r0 + i0 * dr - D) / 20.0);
  std::vector<float> grey(total);
  for (int i2 = 0; i2 < n[2]; ++i2) {
    for (int i1 = 0; i1 < n[1]; ++i1) {
      const std::size_t ray_index =
          static_cast<std::size_t>(i1) + static_cast<std::size_t>(n[1]) * i2;
      const std::size_t base = static_cast<std::size_t>(n[0]) * ray_index;
      for (int i0 = 0; i0 < n[0]; ++i0) {
        const double att = attenuation[static_cast<std::size_t>(i0)];
        std::complex<double> field =
            (coherent[base + i0] + speck[base + i0] * norm) * att * gain[ray_index];
        field += o.noise * std::complex<double>(rng.normal(), rng.normal()) * std::sqrt(0.5);
        const double db = 10.0 * std::log10(std::max(std::norm(field), 1e-24));
        grey[base + i0] = static_cast<float>(
            255.0 * std::clamp((db + o.dynamic_range_db) / o.dynamic_range_db, 0.0, 1.0));
      }
    }
  }
  // Scan conversion to the Cartesian volume (trilinear in beam space; 0 outside the sector).
  ImageVolume out = g.grid;
  out.time_s = f.time_s;
  out.data.assign(out.num_voxels(), 0.0f);
  const int N0 = out.size[0], N1 = out.size[1], N2 = out.size[2];
  for (int k = 0; k < N2; ++k) {
    for (int j = 0; j < N1; ++j) {
      for (int i = 0; i < N0; ++i) {
        const Eigen::Vector3d v = g.axes.transpose() * (out.position(i, j, k) - g.apex);
        if (v.z() <= 1e-6) continue;
        const double r = v.norm();
        const double a1 = (std::atan(v.x() / v.z()) - th0) / dth,
                     a2 = (std::atan(v.y() / v.z()) - th0) / dth;
        const double a0 = (r - r0) / dr;
        if (a0 < 0 || a1 < 0 || a2 < 0 || a0 > n[0] - 1 || a1 > n[1] - 1 || a2 > n[2] - 1) continue;
        const int b0 = std::min(static_cast<int>(a0), n[0] - 2),
                  b1 = std::min(static_cast<int>(a1), n[1] - 2),
                  b2 = std::min(static_cast<int>(a2), n[2] - 2);
        const double f0 = a0 - b0, f1 = a1 - b1, f2 = a2 - b2;
        double s = 0;
        for (int c = 0; c < 8; ++c) {
          const int c0 = c & 1, c1 = (c >> 1) & 1, c2 = (c >> 2) & 1;
          const double w = (c0 ? f0 : 1 - f0) * (c1 ? f1 : 1 - f1) * (c2 ? f2 : 1 - f2);
          s += w * static_cast<double>(grey[static_cast<std::size_t>(b0 + c0) +
                                            static_cast<std::size_t>(n[0]) *
                                                (static_cast<std::size_t>(b1 + c1) +
                                                 static_cast<std::size_t>(n[1]) * (b2 + c2))]);
        }
        out.data[static_cast<std::size_t>(i) +
                 static_cast<std::size_t>(N0) * (j + static_cast<std::size_t>(N1) * k)] =
            static_cast<float>(s);
      }
    }
  }
  return out;
}

std::vector<ImageVolume> render_tee(const ValveSequence& seq, const TeeRenderOptions& o) {
  const TeeGeometry g = tee_geometry(seq, o);
  std::vector<ImageVolume> out;
  for (int f = 0; f < seq.num_frames(); ++f) out.push_back(render_tee_frame(seq, f, g, o));
  return out;
}

}  // namespace mvtwin::detection
