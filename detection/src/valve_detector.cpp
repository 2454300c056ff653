#include "mvtwin/detection/valve_detector.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <numeric>

#include <zlib.h>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/rng.h"
#include "mvtwin/detection/integral_volume.h"

namespace mvtwin::detection {
namespace {

constexpr double kPositionSigmaMm = 3.0, kLandmarkSigmaMm = 2.0, kBoundarySigmaMm = 1.0;
constexpr int kContext = 3;               // offset from the detected centre, image axes, mm
constexpr int kHypotheses = 3;            // position hypotheses in a fresh volume
constexpr double kCentreMarginMm = 10.0;  // around the training valves' centres

/// World <-> voxel index of one volume.
struct Voxels {
  explicit Voxels(const ImageVolume& im)
      : origin(im.origin),
        M(im.direction * im.spacing.asDiagonal()),
        Minv(M.inverse()),
        size(im.size),
        voxel_mm(im.spacing.mean()) {}
  Eigen::Vector3d index(const Eigen::Vector3d& x) const { return Minv * (x - origin); }
  Eigen::Vector3d world(const Eigen::Vector3d& i) const { return origin + M * i; }
  Eigen::Vector3i nearest(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d i = index(x);
    return Eigen::Vector3i(static_cast<int>(std::lround(i[0])), static_cast<int>(std::lround(i[1])),
                           static_cast<int>(std::lround(i[2])));
  }
  /// The volume's centre, mm.
  Eigen::Vector3d centre() const {
    return world(Eigen::Vector3d(0.5 * (size[0] - 1), 0.5 * (size[1] - 1), 0.5 * (size[2] - 1)));
  }
  bool inside(const Eigen::Vector3i& p) const {
    return p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && p[0] < size[0] && p[1] < size[1] &&
           p[2] < size[2];
  }
  Eigen::Vector3d origin;
  Eigen::Matrix3d M, Minv;
  std::array<int, 3> size;
  double voxel_mm;
};

cv::Ptr<cv::ml::RTrees> make_forest(const DetectorOptions& o) {
  cv::Ptr<cv::ml::RTrees> f = cv::ml::RTrees::create();
  f->setMaxDepth(o.max_depth);
  f->setMinSampleCount(5);
  f->setRegressionAccuracy(0.0f);
  f->setUseSurrogates(false);
  f->setCalculateVarImportance(false);
  f->setActiveVarCount(0);
  f->setTermCriteria(cv::TermCriteria(cv::TermCriteria::MAX_ITER, o.trees, 0.0));
  return f;
}

/// Features of voxel p, with the context (p's offset from `centre` in image axes) when given.
void features(const IntegralVolume& iv, const ImageVolume& im, const Voxels& vx,
              const Eigen::Vector3i& p, const std::vector<int>& scales,
              const Eigen::Vector3d* centre, float* out) {
  voxel_features(iv, im, p, scales, out);
  if (centre) {
    const Eigen::Vector3d off = im.direction.transpose() * (vx.world(p.cast<double>()) - *centre);
    float* c = out + feature_count(scales);
    for (int a = 0; a < 3; ++a) c[a] = static_cast<float>(off[a]);
  }
}

std::vector<float> predict(const cv::Ptr<cv::ml::RTrees>& f, cv::Mat& samples) {
  cv::Mat out;
  f->predict(samples, out);
  std::vector<float> r(static_cast<std::size_t>(out.rows));
  for (int i = 0; i < out.rows; ++i) r[static_cast<std::size_t>(i)] = out.at<float>(i, 0);
  return r;
}

/// A peak of the predicted proximity: the proximity-weighted mean of the best candidates
/// within `radius` mm of the best one (never averaging two separate peaks).
struct Peak {
  Eigen::Vector3d x;
  float score = 0;
};

/// Up to `count` peaks, best first, each at least `separation` mm from the better ones.
std::vector<Peak> peaks(const std::vector<Eigen::Vector3d>& xs, const std::vector<float>& score,
                        int count, double radius, double separation, int top = 6) {
  std::vector<std::size_t> order(xs.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return score[a] > score[b]; });
  std::vector<Peak> out;
  for (std::size_t i : order) {
    if (static_cast<int>(out.size()) >= count) break;
    bool near = false;
    for (const Peak& q : out) near = near || (xs[i] - q.x).norm() < separation;
    if (near) continue;
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    double w = 0;
    int used = 0;
    for (std::size_t j : order) {
      if (used >= top || score[j] < 0.5f * score[i]) break;
      if ((xs[j] - xs[i]).norm() > radius) continue;
      const double wj = std::max(1e-6, static_cast<double>(score[j]));
      s += wj * xs[j];
      w += wj;
      ++used;
    }
    out.push_back({s / w, score[i]});
  }
  return out;
}

/// Unit normals of the grid (towards the atrium side of the u x v orientation).
Points3 grid_normals(const Points3& P, int ures, int vres) {
  Points3 N(P.rows(), 3);
  auto at = [&](int u, int v) {
    u = ((u % ures) + ures) % ures;
    v = std::clamp(v, 0, vres - 1);
    return Eigen::Vector3d(P.row(static_cast<Eigen::Index>(v) * ures + u).transpose());
  };
  for (int v = 0; v < vres; ++v)
    for (int u = 0; u < ures; ++u) {
      const Eigen::Vector3d du = at(u + 1, v) - at(u - 1, v), dv = at(u, v + 1) - at(u, v - 1);
      Eigen::Vector3d n = du.cross(dv);
      const double len = n.norm();
      N.row(static_cast<Eigen::Index>(v) * ures + u) =
          (len > 1e-12 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::UnitZ()).transpose();
    }
  return N;
}

}  // namespace

ValveFrame with_surface_tips(const ValveFrame& frame) {
  ValveFrame out = frame;
  if (!frame.la_surface) return out;
  const std::array<std::pair<Landmark, double>, 2> tips = {
      std::pair{Landmark::kAnteriorLeafletTip, 0.25},
      std::pair{Landmark::kPosteriorLeafletTip, 0.75}};
  for (const auto& [l, s] : tips) {
    const auto i = static_cast<std::size_t>(index(l));
    if (out.landmark_observed[i]) continue;
    out.landmarks[i] = frame.la_surface->sample(s, 1.0);
    out.landmark_observed[i] = true;
  }
  return out;
}

std::string DetectorOptions::invalid() const {
  if (scales.empty()) return "no feature scales";
  for (int s : scales)
    if (s < 1 || s > 32) return "feature scales must be 1..32 voxels";
  if (trees < 1 || trees > 1000) return "trees must be 1..1000";
  if (max_depth < 2 || max_depth > 30) return "max_depth must be 2..30";
  if (samples_per_volume < 50) return "samples_per_volume must be at least 50";
  if (!(position_step_mm > 0 && landmark_search_mm > 0 && track_search_mm > 0 &&
        normal_search_mm > 0))
    return "search sizes must be positive";
  if (surface_iterations < 0 || surface_iterations > 20) return "surface_iterations must be 0..20";
  return "";
}

struct ValveDetector::Impl {
  DetectorOptions options;
  ShapeModel shape;
  cv::Ptr<cv::ml::RTrees> position, boundary;
  std::vector<cv::Ptr<cv::ml::RTrees>> landmarks;  // kNumLandmarks
  std::vector<Eigen::Vector3d> landmark_offset;    // mean landmark - centre, image axes, mm
  // Where the training valves' centres were relative to their volume's centre (image axes, mm).
  bool has_centre_range = false;
  Eigen::Vector3d centre_lo = Eigen::Vector3d::Zero(), centre_hi = Eigen::Vector3d::Zero();

  int nf() const { return feature_count(options.scales); }
};

ValveDetector::ValveDetector() : impl_(std::make_unique<Impl>()) {}
ValveDetector::~ValveDetector() = default;
ValveDetector::ValveDetector(ValveDetector&&) noexcept = default;
ValveDetector& ValveDetector::operator=(ValveDetector&&) noexcept = default;
const ShapeModel& ValveDetector::shape() const { return impl_->shape; }
const DetectorOptions& ValveDetector::options() const { return impl_->options; }

ValveDetector ValveDetector::train(const std::vector<TrainingVolume>& data,
                                   const DetectorOptions& o,
                                   const std::function<void(const std::string&)>& progress) {
  if (const std::string e = o.invalid(); !e.empty()) throw Error("detector: " + e);
  // Closing and closed frames leave the leaflet tips unobserved (they meet at the coaptation);
  // their tips are taken from the surface as in the open frames (the free edge's middle of each
  // leaflet), so that closed valves train the detectors and the shape model too.
  std::vector<ValveFrame> completed;
  completed.reserve(data.size());
  std::vector<TrainingVolume> usable;
  for (const TrainingVolume& t : data) {
    if (!t.image || !t.truth || !t.truth->la_surface ||
        t.image->data.size() != t.image->num_voxels())
      continue;
    completed.push_back(with_surface_tips(*t.truth));
    bool all = true;
    for (int l = 0; l < kNumLandmarks; ++l)
      all = all && completed.back().landmark_observed[static_cast<std::size_t>(l)];
    if (all)
      usable.push_back({t.image, &completed.back()});
    else
      completed.pop_back();
  }
  if (usable.size() < 3)
    throw Error("detector: needs at least 3 training volumes with landmarks and a surface, got " +
                std::to_string(usable.size()));
  ValveDetector d;
  Impl& m = *d.impl_;
  m.options = o;
  auto say = [&](const std::string& s) {
    if (progress) progress(s);
  };
  say("shape model");
  std::vector<const ValveFrame*> truths;
  for (const auto& t : usable) truths.push_back(t.truth);
  m.shape = ShapeModel::train(truths);

  const int nf = m.nf(), nc = nf + kContext;
  Rng rng(o.seed);
  auto gauss = [](double x, double s) {
    return static_cast<float>(std::exp(-0.5 * x * x / (s * s)));
  };
  cv::Mat pos_x(0, nf, CV_32F), pos_y(0, 1, CV_32F), bnd_x(0, nc, CV_32F), bnd_y(0, 1, CV_32F);
  std::vector<cv::Mat> lm_x, lm_y;  // one (not shared) matrix per landmark
  for (int l = 0; l < kNumLandmarks; ++l) {
    lm_x.emplace_back(0, nc, CV_32F);
    lm_y.emplace_back(0, 1, CV_32F);
  }
  m.landmark_offset.assign(kNumLandmarks, Eigen::Vector3d::Zero());
  std::vector<float> row(static_cast<std::size_t>(nc));
  auto push = [&](cv::Mat& X, cv::Mat& Y, float y, int cols) {
    X.push_back(cv::Mat(1, cols, CV_32F, row.data()).clone());
    Y.push_back(y);
  };
  for (const TrainingVolume& t : usable) {
    const ImageVolume& im = *t.image;
    const ValveFrame& f = *t.truth;
    const IntegralVolume iv(im);
    const Voxels vx(im);
    const Eigen::Vector3d c = f.annulus.colwise().mean().transpose();
    for (int l = 0; l < kNumLandmarks; ++l)
      m.landmark_offset[static_cast<std::size_t>(l)] +=
          im.direction.transpose() * (f.landmarks[static_cast<std::size_t>(l)] - c);
    {
      const Eigen::Vector3d mid = vx.centre();
      const Eigen::Vector3d off = im.direction.transpose() * (c - mid);
      m.centre_lo = m.has_centre_range ? Eigen::Vector3d(m.centre_lo.cwiseMin(off)) : off;
      m.centre_hi = m.has_centre_range ? Eigen::Vector3d(m.centre_hi.cwiseMax(off)) : off;
      m.has_centre_range = true;
    }
    auto random_offset = [&](double r) {
      return Eigen::Vector3d(rng.uniform(-r, r), rng.uniform(-r, r), rng.uniform(-r, r));
    };
    // Position: near the centre, around it, anywhere.
    for (int s = 0; s < o.samples_per_volume; ++s) {
      const double u = rng.uniform();
      Eigen::Vector3i p;
      if (u < 0.3)
        p = vx.nearest(c + random_offset(4.0));
      else if (u < 0.6)
        p = vx.nearest(c + random_offset(15.0));
      else
        p = Eigen::Vector3i(rng.uniform_int(0, im.size[0] - 1), rng.uniform_int(0, im.size[1] - 1),
                            rng.uniform_int(0, im.size[2] - 1));
      if (!vx.inside(p)) continue;
      features(iv, im, vx, p, o.scales, nullptr, row.data());
      push(pos_x, pos_y, gauss((vx.world(p.cast<double>()) - c).norm(), kPositionSigmaMm), nf);
    }
    // Landmarks: around each, with the context measured from a centre detected with error.
    for (int l = 0; l < kNumLandmarks; ++l) {
      const Eigen::Vector3d L = f.landmarks[static_cast<std::size_t>(l)];
      for (int s = 0; s < o.samples_per_volume / 3; ++s) {
        const Eigen::Vector3d cn = c + random_offset(2.5);
        const Eigen::Vector3i p =
            vx.nearest(L + random_offset(rng.uniform() < 0.4 ? 3.0 : o.landmark_search_mm));
        if (!vx.inside(p)) continue;
        features(iv, im, vx, p, o.scales, &cn, row.data());
        push(lm_x[static_cast<std::size_t>(l)], lm_y[static_cast<std::size_t>(l)],
             gauss((vx.world(p.cast<double>()) - L).norm(), kLandmarkSigmaMm), nc);
      }
    }
    // Boundary: along the surface normals.
    const Points3& P = f.la_surface->points();
    const Points3 N = grid_normals(P, f.la_surface->ures(), f.la_surface->vres());
    for (int s = 0; s < o.samples_per_volume; ++s) {
      const auto k = static_cast<Eigen::Index>(rng.uniform_int(0, static_cast<int>(P.rows()) - 1));
      const double off = rng.uniform() < 0.4
                             ? rng.uniform(-1.5, 1.5)
                             : rng.uniform(-o.normal_search_mm - 2, o.normal_search_mm + 2);
      const Eigen::Vector3d x = P.row(k).transpose() + off * N.row(k).transpose();
      const Eigen::Vector3i p = vx.nearest(x);
      if (!vx.inside(p)) continue;
      const Eigen::Vector3d cn = c + random_offset(2.5);
      features(iv, im, vx, p, o.scales, &cn, row.data());
      push(bnd_x, bnd_y, gauss(off, kBoundarySigmaMm), nc);
    }
  }
  for (auto& off : m.landmark_offset) off /= static_cast<double>(usable.size());
  say("position detector (" + std::to_string(pos_x.rows) + " samples)");
  m.position = make_forest(o);
  m.position->train(cv::ml::TrainData::create(pos_x, cv::ml::ROW_SAMPLE, pos_y));
  m.landmarks.resize(kNumLandmarks);
  for (int l = 0; l < kNumLandmarks; ++l) {
    say("landmark detector " + std::string(kLandmarkNames[static_cast<std::size_t>(l)]));
    m.landmarks[static_cast<std::size_t>(l)] = make_forest(o);
    m.landmarks[static_cast<std::size_t>(l)]->train(cv::ml::TrainData::create(
        lm_x[static_cast<std::size_t>(l)], cv::ml::ROW_SAMPLE, lm_y[static_cast<std::size_t>(l)]));
  }
  say("boundary detector (" + std::to_string(bnd_x.rows) + " samples)");
  m.boundary = make_forest(o);
  m.boundary->train(cv::ml::TrainData::create(bnd_x, cv::ml::ROW_SAMPLE, bnd_y));
  return d;
}

ValveFrame ValveDetector::detect(const ImageVolume& im, const ValveFrame* previous,
                                 DetectionInfo* info) const {
  const auto t0 = std::chrono::steady_clock::now();
  const Impl& m = *impl_;
  if (!m.position) throw Error("detector: not trained");
  if (im.data.size() != im.num_voxels() || im.num_voxels() == 0)
    throw Error("detector: the volume is empty or its data does not match its size");
  const IntegralVolume iv(im);
  const Voxels vx(im);
  const int nf = m.nf(), nc = nf + kContext;
  const DetectorOptions& o = m.options;

  auto score = [&](const cv::Ptr<cv::ml::RTrees>& f, const std::vector<Eigen::Vector3d>& pts,
                   const Eigen::Vector3d* centre) {
    const int cols = centre ? nc : nf;
    cv::Mat X(static_cast<int>(pts.size()), cols, CV_32F, cv::Scalar(0));
    for (std::size_t i = 0; i < pts.size(); ++i) {
      Eigen::Vector3i p = vx.nearest(pts[i]);
      for (int a = 0; a < 3; ++a) p[a] = std::clamp(p[a], 0, im.size[a] - 1);
      features(iv, im, vx, p, o.scales, centre, X.ptr<float>(static_cast<int>(i)));
    }
    return predict(f, X);
  };
  // Candidates on a cube of half-width r (mm) around x, step st, in the volume's axes.
  auto cube = [&](const Eigen::Vector3d& x, double r, double st) {
    std::vector<Eigen::Vector3d> out;
    for (double a = -r; a <= r + 1e-9; a += st)
      for (double b = -r; b <= r + 1e-9; b += st)
        for (double c = -r; c <= r + 1e-9; c += st)
          out.push_back(x + im.direction * Eigen::Vector3d(a, b, c));
    return out;
  };
  const double h = std::max(1.0, vx.voxel_mm);  // finest search step, mm

  // 1. Position: a few separate hypotheses in a fresh volume (the landmarks decide), the best
  // near the previous frame's when tracking.
  std::vector<Eigen::Vector3d> hypotheses;
  if (previous) {
    const std::vector<Eigen::Vector3d> xs =
        cube(previous->annulus.colwise().mean().transpose(), o.track_search_mm, 2 * h);
    hypotheses.push_back(peaks(xs, score(m.position, xs, nullptr), 1, 3 * h, 0.0).front().x);
  } else {
    const int step = std::max(1, static_cast<int>(std::lround(o.position_step_mm / vx.voxel_mm)));
    const int margin = o.scales.back();
    const Eigen::Vector3d mid = vx.centre();
    std::vector<Eigen::Vector3d> xs;
    for (int k = margin; k < im.size[2] - margin; k += step)
      for (int j = margin; j < im.size[1] - margin; j += step)
        for (int i = margin; i < im.size[0] - margin; i += step) {
          const Eigen::Vector3d x = vx.world(Eigen::Vector3d(i, j, k));
          if (m.has_centre_range) {  // where training valves were, with a margin
            const Eigen::Vector3d off = im.direction.transpose() * (x - mid);
            if (((off - m.centre_lo).array() < -kCentreMarginMm).any() ||
                ((off - m.centre_hi).array() > kCentreMarginMm).any())
              continue;
          }
          xs.push_back(x);
        }
    if (xs.empty()) throw Error("detector: the volume is too small to search");
    for (const Peak& pk :
         peaks(xs, score(m.position, xs, nullptr), kHypotheses, 2.0 * step * vx.voxel_mm, 10.0))
      hypotheses.push_back(pk.x);
  }

  // 2. Landmarks, each in a box around its expected place (coarse, then on the voxel grid), with
  // the offset from the centre as context. Their mean peak score rates a position hypothesis.
  struct Found {
    std::array<Eigen::Vector3d, kNumLandmarks> at;
    double score = 0;
  };
  auto find_landmarks = [&](const Eigen::Vector3d& centre, bool from_previous, bool refine) {
    Found f;
    for (int l = 0; l < kNumLandmarks; ++l) {
      const auto li = static_cast<std::size_t>(l);
      const Eigen::Vector3d guess =
          from_previous ? previous->landmarks[li]
                        : Eigen::Vector3d(centre + im.direction * m.landmark_offset[li]);
      std::vector<Eigen::Vector3d> cand =
          cube(guess, previous ? o.track_search_mm : o.landmark_search_mm, 2 * h);
      Peak best = peaks(cand, score(m.landmarks[li], cand, &centre), 1, 3 * h, 0.0).front();
      if (refine) {
        cand = cube(best.x, 2 * h, h);
        best = peaks(cand, score(m.landmarks[li], cand, &centre), 1, 1.5 * h, 0.0, 4).front();
      }
      f.at[li] = best.x;
      f.score += static_cast<double>(best.score) / kNumLandmarks;
    }
    return f;
  };
  ValveFrame out;
  out.time_s = im.time_s;
  auto placing = [&] {
    Points3 L(static_cast<Eigen::Index>(kPlacingLandmarks.size()), 3);
    for (std::size_t i = 0; i < kPlacingLandmarks.size(); ++i)
      L.row(static_cast<Eigen::Index>(i)) = out.landmark(kPlacingLandmarks[i]).transpose();
    return L;
  };
  auto take = [&](const Found& f) {
    out.landmarks = f.at;
    out.landmark_observed.fill(true);
  };
  Eigen::Vector3d centre = hypotheses.front();
  if (previous) {
    take(find_landmarks(centre, true, true));
  } else {
    // The hypothesis whose landmarks the detectors believe most; then the centre again from the
    // mean shape those landmarks place, and the landmarks once more around it.
    Found best;
    best.score = -1;
    for (const Eigen::Vector3d& c : hypotheses) {
      const Found f = find_landmarks(c, false, hypotheses.size() == 1);
      if (f.score > best.score) {
        best = f;
        centre = c;
      }
    }
    take(best);
    const Points3 placed = m.shape.place_mean(placing());
    const Eigen::Vector3d c2 = placed.topRows(m.shape.ures()).colwise().mean().transpose();
    const bool moved = (c2 - centre).norm() >= 1.0;
    if (moved) centre = c2;
    if (moved || hypotheses.size() > 1) take(find_landmarks(centre, false, true));  // refined
  }

  // 3. Surface: placed by the landmarks, refined along the normals, kept in the shape space.
  const Points3 L = placing();
  const Similarity place = m.shape.placement(L);
  const int ures = m.shape.ures(), vres = m.shape.vres();
  Points3 P = m.shape.place_mean(L);
  if (previous && previous->la_surface) {
    const LeafletGrid g =
        previous->la_surface->ures() == ures && previous->la_surface->vres() == vres
            ? *previous->la_surface
            : previous->la_surface->resampled(ures, vres);
    P = m.shape.constrain(g.points(), place);
  }
  for (int it = 0; it < o.surface_iterations; ++it) {
    const double r = o.normal_search_mm * (1.0 - 0.5 * it / std::max(1, o.surface_iterations));
    const double st = vx.voxel_mm;
    const int ns = 2 * static_cast<int>(r / st) + 1;
    const Points3 N = grid_normals(P, ures, vres);
    std::vector<Eigen::Vector3d> cand;
    cand.reserve(static_cast<std::size_t>(P.rows()) * static_cast<std::size_t>(ns));
    for (Eigen::Index k = 0; k < P.rows(); ++k)
      for (int s = 0; s < ns; ++s)
        cand.push_back(P.row(k).transpose() + (-r + s * st) * N.row(k).transpose());
    const std::vector<float> sc = score(m.boundary, cand, &centre);
    Points3 moved = P;
    for (Eigen::Index k = 0; k < P.rows(); ++k) {
      int best = -1;
      float bs = 0.25f;  // below this, no boundary seen: keep the point
      for (int s = 0; s < ns; ++s) {
        const float v = sc[static_cast<std::size_t>(k * ns + s)];
        if (v > bs) {
          bs = v;
          best = s;
        }
      }
      if (best < 0) continue;
      // Sub-sample: the vertex of the parabola through the best score and its neighbours.
      double d = 0;
      if (best > 0 && best < ns - 1) {
        const double sm = static_cast<double>(sc[static_cast<std::size_t>(k * ns + best - 1)]),
                     s0 = static_cast<double>(bs),
                     sp = static_cast<double>(sc[static_cast<std::size_t>(k * ns + best + 1)]);
        const double den = sm - 2 * s0 + sp;
        if (den < -1e-9) d = std::clamp(0.5 * (sm - sp) / den, -0.5, 0.5);
      }
      moved.row(k) = (cand[static_cast<std::size_t>(k * ns + best)] + d * st * N.row(k).transpose())
                         .transpose();
    }
    P = m.shape.constrain(moved, place);
  }
  out.la_surface = LeafletGrid(ures, vres, P);
  out.annulus = P.topRows(ures);
  if (info) {
    info->centre = out.annulus.colwise().mean().transpose();
    info->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return out;
}

std::vector<ValveFrame> ValveDetector::detect_sequence(const std::vector<ImageVolume>& frames,
                                                       std::vector<DetectionInfo>* info) const {
  std::vector<ValveFrame> out;
  if (info) info->clear();
  for (std::size_t f = 0; f < frames.size(); ++f) {
    DetectionInfo di;
    out.push_back(detect(frames[f], f ? &out.back() : nullptr, &di));
    if (info) info->push_back(di);
  }
  // Temporal smoothing: each inner frame averaged with its neighbours (1/4, 1/2, 1/4).
  if (out.size() >= 3) {
    const std::vector<ValveFrame> raw = out;
    for (std::size_t f = 1; f + 1 < raw.size(); ++f) {
      for (int l = 0; l < kNumLandmarks; ++l) {
        const auto i = static_cast<std::size_t>(l);
        out[f].landmarks[i] = 0.25 * raw[f - 1].landmarks[i] + 0.5 * raw[f].landmarks[i] +
                              0.25 * raw[f + 1].landmarks[i];
      }
      Points3 P = 0.25 * raw[f - 1].la_surface->points() + 0.5 * raw[f].la_surface->points() +
                  0.25 * raw[f + 1].la_surface->points();
      out[f].annulus = P.topRows(raw[f].la_surface->ures());
      out[f].la_surface = LeafletGrid(raw[f].la_surface->ures(), raw[f].la_surface->vres(), P);
    }
  }
  return out;
}

void ValveDetector::save(const std::filesystem::path& path,
                         const std::vector<std::pair<std::string, std::string>>& provenance) const {
  const Impl& m = *impl_;
  if (!m.position) throw Error("detector: not trained");
  const std::string ext = path.string();
  const bool ok_ext = ext.ends_with(".yml") || ext.ends_with(".yml.gz") || ext.ends_with(".yaml");
  if (!ok_ext) throw Error(path.string() + ": a detector model is written as .yml or .yml.gz");
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    // FileStorage picks the format from the name: give the temporary the same ending.
    const std::string name = tmp.string() + (ext.ends_with(".gz") ? ".yml.gz" : ".yml");
    {
      cv::FileStorage fs(name, cv::FileStorage::WRITE);
      if (!fs.isOpened()) throw Error(path.string() + ": cannot be written");
      fs << "format"
         << "mvtwin-valve-detector"
         << "format_version" << 1;
      fs << "provenance"
         << "{";
      for (const auto& [k, v] : provenance) fs << k << v;
      fs << "}";
      fs << "scales" << m.options.scales;
      fs << "options"
         << "{"
         << "trees" << m.options.trees << "max_depth" << m.options.max_depth << "samples_per_volume"
         << m.options.samples_per_volume << "position_step_mm" << m.options.position_step_mm
         << "landmark_search_mm" << m.options.landmark_search_mm << "track_search_mm"
         << m.options.track_search_mm << "normal_search_mm" << m.options.normal_search_mm
         << "surface_iterations" << m.options.surface_iterations << "seed"
         << static_cast<double>(m.options.seed) << "}";
      fs << "shape_model" << m.shape.serialize();
      std::vector<double> offs;
      for (const auto& v : m.landmark_offset) offs.insert(offs.end(), v.data(), v.data() + 3);
      fs << "landmark_offset" << offs;
      if (m.has_centre_range)
        fs << "centre_range" << std::vector<double>{m.centre_lo[0], m.centre_lo[1], m.centre_lo[2],
                                                    m.centre_hi[0], m.centre_hi[1], m.centre_hi[2]};
      fs << "position"
         << "{";
      m.position->write(fs);
      fs << "}";
      fs << "boundary"
         << "{";
      m.boundary->write(fs);
      fs << "}";
      for (int l = 0; l < kNumLandmarks; ++l) {
        fs << ("landmark_" + std::string(kLandmarkNames[static_cast<std::size_t>(l)])) << "{";
        m.landmarks[static_cast<std::size_t>(l)]->write(fs);
        fs << "}";
      }
    }
    std::filesystem::rename(name, tmp);
  });
}

namespace {

/// The text of a model file, gunzipped when it ends in .gz (at most kMaxModelBytes either way).
constexpr std::size_t kMaxModelBytes = std::size_t{1} << 30;
std::string model_text(const std::filesystem::path& path, const std::string& what) {
  std::string text;
  gzFile f = gzopen(path.c_str(), "rb");  // reads plain files as they are
  if (!f) throw Error(what + ": cannot be opened for reading (permissions?)");
  char buf[1 << 16];
  int n = 0;
  while ((n = gzread(f, buf, sizeof buf)) > 0) {
    text.append(buf, static_cast<std::size_t>(n));
    if (text.size() > kMaxModelBytes) {
      gzclose(f);
      throw Error(what + ": more than 1 GB of model text (not a detector model?)");
    }
  }
  int code = Z_OK;
  const char* message = n < 0 ? gzerror(f, &code) : nullptr;
  const std::string why = message ? message : "";
  gzclose(f);
  if (n < 0) throw Error(what + ": the compressed model is corrupt (" + why + ")");
  return text;
}

/// Refuses model text that does not look as train-detector writes it (OpenCV's YAML writer):
/// OpenCV 4.6's YAML parser never returns on some malformed text, found by the fuzzer: 84 bytes
/// of several "%YAML" documents with NUL bytes between them, 135 bytes with bytes above 127 and
/// an unclosed '[', 33 bytes of flow sequences with an empty item
/// (tests/fuzz/regressions/fuzz_detector_model/). These checks narrow what reaches the parser;
/// they do not make it safe.
void check_model_text(const std::string& text, const std::string& what) {
  if (text.find('\0') != std::string::npos)
    throw Error(what + ": not a detector model (a NUL byte: binary, not YAML text)");
  if (text.rfind("%YAML:1.0\n---\n", 0) != 0 && text.rfind("%YAML:1.0\r\n---\r\n", 0) != 0)
    throw Error(what + ": not a detector model (it must start with '%YAML:1.0' and '---')");
  if (text.find("%YAML", 1) != std::string::npos || text.find("---", 14) != std::string::npos ||
      text.find("...", 0) != std::string::npos)
    throw Error(what + ": not a detector model (more than one YAML document)");
  // The document is a mapping: every line that is not indented starts with a key (a 33-byte
  // document of flow sequences and empty items hung the parser: the fuzzer's fourth run).
  for (std::size_t at = text.find('\n', text.find("---")) + 1; at < text.size();) {
    const std::size_t eol = std::min(text.find('\n', at), text.size());
    const std::string line = text.substr(at, eol - at);
    const std::size_t colon = line.find(':');
    const bool indented = !line.empty() && (line[0] == ' ' || line[0] == '\t');
    bool key = colon != std::string::npos && colon > 0 &&
               std::isalpha(static_cast<unsigned char>(line[0]));
    for (std::size_t k = 0; key && k < colon; ++k)
      key = std::isalnum(static_cast<unsigned char>(line[k])) || line[k] == '_' || line[k] == '-';
    if (!indented && !(line.empty() || line == "\r") && !key)
      throw Error(what + ": not a detector model (line '" + line.substr(0, 40) +
                  "' is neither a key nor indented)");
    at = eol + 1;
  }
  // No empty items in a flow sequence ("[ ,", ", ,", ", ]"): OpenCV's writer never makes one.
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '[' && text[i] != ',') continue;
    std::size_t j = i + 1;
    while (j < text.size() && std::isspace(static_cast<unsigned char>(text[j]))) ++j;
    if (j < text.size() && (text[j] == ',' || (text[j] == ']' && text[i] == ',')))
      throw Error(what + ": not a detector model (an empty item in a sequence at offset " +
                  std::to_string(i) + ")");
  }
  // What OpenCV's writer puts in a model: printable ASCII, tabs and line ends, balanced flow
  // brackets outside quotes, no anchors or aliases. Its parser also never returned on a
  // 135-byte text of one document with bytes above 127 and an unclosed '[' (the fuzzer's
  // second 10-minute run).
  std::vector<char> open;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (!(c == '\n' || c == '\r' || c == '\t' || (c >= 0x20 && c < 0x7f)))
      throw Error(what + ": not a detector model (byte " + std::to_string(c) + " at offset " +
                  std::to_string(i) + ": not the ASCII text train-detector writes)");
    if (c == '"') quoted = !quoted;
    if (quoted) continue;
    if (c == '*' || c == '&')
      throw Error(what + ": not a detector model (a YAML anchor or alias at offset " +
                  std::to_string(i) + ")");
    if (c == '[' || c == '{') {
      open.push_back(c == '[' ? ']' : '}');
      if (open.size() > 64) throw Error(what + ": not a detector model (brackets nested > 64)");
    } else if (c == ']' || c == '}') {
      if (open.empty() || open.back() != static_cast<char>(c))
        throw Error(what + ": not a detector model (unbalanced brackets at offset " +
                    std::to_string(i) + ")");
      open.pop_back();
    }
  }
  if (quoted || !open.empty())
    throw Error(what + ": not a detector model (an unclosed quote or bracket)");
}

/// Opens a model file for reading; throws mvtwin::Error naming it when it is missing, unreadable
/// or not an mvtwin detector model.
cv::FileStorage open_model(const std::filesystem::path& path) {
  const std::string what = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(what + ": no such file");
  // OpenCV 4.6's YAML parser never returns on some malformed text: it reads only text that
  // passed check_model_text, from memory.
  const std::string text = model_text(path, what);
  check_model_text(text, what);
  cv::FileStorage fs;
  try {
    fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const std::exception& e) {  // cv::Exception, std::length_error from the parser
    throw Error(what + ": not a readable detector model (" + std::string(e.what()).substr(0, 200) +
                ")");
  }
  if (!fs.isOpened()) throw Error(what + ": not a readable detector model");
  if (fs["format"].empty() || static_cast<std::string>(fs["format"]) != "mvtwin-valve-detector")
    throw Error(what + ": not an mvtwin valve detector model");
  return fs;
}

}  // namespace

// OpenCV reports a malformed file or node (a string where numbers are expected, a matrix of
// the wrong shape, a broken forest) by throwing cv::Exception, or lets std::length_error
// through, from opening and from any read: found by the fuzzer
// (tests/fuzz/fuzz_detector_model.cpp). The function-try-block turns them into the error naming
// the file; mvtwin::Error passes through.
ValveDetector ValveDetector::load(const std::filesystem::path& path) try {
  const std::string what = path.string();
  cv::FileStorage fs = open_model(path);
  if (static_cast<int>(fs["format_version"]) != 1)
    throw Error(what + ": detector model format version " +
                std::to_string(static_cast<int>(fs["format_version"])) + " is not supported (1)");
  ValveDetector d;
  Impl& m = *d.impl_;
  fs["scales"] >> m.options.scales;
  const cv::FileNode on = fs["options"];
  m.options.trees = static_cast<int>(on["trees"]);
  m.options.max_depth = static_cast<int>(on["max_depth"]);
  m.options.samples_per_volume = static_cast<int>(on["samples_per_volume"]);
  m.options.position_step_mm = static_cast<double>(on["position_step_mm"]);
  m.options.landmark_search_mm = static_cast<double>(on["landmark_search_mm"]);
  m.options.track_search_mm = static_cast<double>(on["track_search_mm"]);
  m.options.normal_search_mm = static_cast<double>(on["normal_search_mm"]);
  m.options.surface_iterations = static_cast<int>(on["surface_iterations"]);
  const double seed = static_cast<double>(on["seed"]);
  if (!(seed >= 0.0 && seed < 18446744073709551616.0))  // 2^64; NaN fails too
    throw Error(what + ": bad detector options: the seed is not a whole number >= 0");
  m.options.seed = static_cast<std::uint64_t>(seed);
  if (const std::string e = m.options.invalid(); !e.empty())
    throw Error(what + ": bad detector options: " + e);
  std::vector<double> shape, offs;
  fs["shape_model"] >> shape;
  m.shape = ShapeModel::deserialize(shape);
  fs["landmark_offset"] >> offs;
  if (offs.size() != 3 * kNumLandmarks) throw Error(what + ": bad landmark offsets");
  for (int l = 0; l < kNumLandmarks; ++l)
    m.landmark_offset.emplace_back(offs[3 * l], offs[3 * l + 1], offs[3 * l + 2]);
  if (!fs["centre_range"].empty()) {  // models written before it was learned search everywhere
    std::vector<double> r;
    fs["centre_range"] >> r;
    if (r.size() != 6) throw Error(what + ": bad centre range");
    m.centre_lo = Eigen::Vector3d(r[0], r[1], r[2]);
    m.centre_hi = Eigen::Vector3d(r[3], r[4], r[5]);
    m.has_centre_range = true;
  }
  auto forest = [&](const std::string& name) {
    cv::Ptr<cv::ml::RTrees> f = cv::ml::RTrees::create();
    if (fs[name].empty()) throw Error(what + ": the model lacks the '" + name + "' detector");
    f->read(fs[name]);
    if (f->empty() || !f->isTrained()) throw Error(what + ": the '" + name + "' detector is empty");
    return f;
  };
  m.position = forest("position");
  m.boundary = forest("boundary");
  for (int l = 0; l < kNumLandmarks; ++l)
    m.landmarks.push_back(
        forest("landmark_" + std::string(kLandmarkNames[static_cast<std::size_t>(l)])));
  return d;
} catch (const Error&) {
  throw;
} catch (const std::exception& e) {  // cv::Exception, and what OpenCV lets through (length_error)
  throw Error(path.string() + ": not a readable detector model (" +
              std::string(e.what()).substr(0, 200) + ")");
}

std::vector<std::pair<std::string, std::string>> ValveDetector::provenance(
    const std::filesystem::path& path) {
  const cv::FileStorage fs = open_model(path);
  std::vector<std::pair<std::string, std::string>> out;
  for (const cv::FileNode& n : fs["provenance"])
    if (n.isString()) out.emplace_back(n.name(), static_cast<std::string>(n));
  return out;
}

}  // namespace mvtwin::detection
