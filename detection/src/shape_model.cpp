#include "mvtwin/detection/shape_model.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "mvtwin/core/error.h"

namespace mvtwin::detection {

Similarity Similarity::inverse() const {
  Similarity s;
  s.scale = 1.0 / scale;
  s.R = R.transpose();
  s.t = -s.scale * s.R * t;
  return s;
}

Similarity fit_similarity(const Points3& from, const Points3& to) {
  if (from.rows() != to.rows() || from.rows() < 3)
    throw Error("similarity: needs at least 3 corresponding points");
  const Eigen::Matrix4d T = Eigen::umeyama(from.transpose(), to.transpose(), true);
  Similarity s;
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  s.scale = std::cbrt(sR.determinant());
  if (!(s.scale > 0) || !std::isfinite(s.scale)) throw Error("similarity: degenerate points");
  s.R = sR / s.scale;
  s.t = T.topRightCorner<3, 1>();
  return s;
}

Points3 placing_landmarks(const ValveFrame& f) {
  Points3 L(static_cast<Eigen::Index>(kPlacingLandmarks.size()), 3);
  for (std::size_t i = 0; i < kPlacingLandmarks.size(); ++i) {
    if (!f.observed(kPlacingLandmarks[i]))
      throw Error("shape model: landmark " + std::string(name(kPlacingLandmarks[i])) +
                  " is not observed");
    L.row(static_cast<Eigen::Index>(i)) = f.landmark(kPlacingLandmarks[i]).transpose();
  }
  return L;
}

namespace {

Points3 transformed(const Points3& P, const Similarity& s) {
  Points3 out(P.rows(), 3);
  for (Eigen::Index i = 0; i < P.rows(); ++i)
    out.row(i) = s.apply(P.row(i).transpose()).transpose();
  return out;
}

Eigen::VectorXd flat(const Points3& P) {
  return Eigen::Map<const Eigen::VectorXd>(P.data(), P.size());
}

Points3 unflat(const Eigen::VectorXd& v) {
  return Eigen::Map<const Points3>(v.data(), v.size() / 3, 3);
}

}  // namespace

ShapeModel ShapeModel::train(const std::vector<const ValveFrame*>& frames, double variance_kept) {
  std::vector<Points3> landmarks, surfaces;
  int ures = 0, vres = 0;
  for (const ValveFrame* f : frames) {
    if (!f || !f->la_surface) continue;
    Points3 L;
    try {
      L = placing_landmarks(*f);
    } catch (const Error&) {
      continue;
    }
    if (ures == 0) {
      ures = f->la_surface->ures();
      vres = f->la_surface->vres();
    }
    const LeafletGrid g = f->la_surface->ures() == ures && f->la_surface->vres() == vres
                              ? *f->la_surface
                              : f->la_surface->resampled(ures, vres);
    landmarks.push_back(L);
    surfaces.push_back(g.points());
  }
  const int n = static_cast<int>(landmarks.size());
  if (n < 3)
    throw Error("shape model: needs at least 3 frames with a surface and landmarks, got " +
                std::to_string(n));
  // Generalized Procrustes of the landmarks: the mean configuration, centred at the origin
  // with unit RMS radius.
  Points3 mean = landmarks.front();
  auto normalize = [](Points3* M) {
    const Eigen::RowVector3d c = M->colwise().mean();
    M->rowwise() -= c;
    *M /= std::sqrt(M->squaredNorm() / static_cast<double>(M->rows()));
  };
  normalize(&mean);
  for (int it = 0; it < 10; ++it) {
    Points3 sum = Points3::Zero(mean.rows(), 3);
    for (const Points3& L : landmarks) sum += transformed(L, fit_similarity(L, mean));
    sum /= n;
    normalize(&sum);
    const double change = (sum - mean).norm();
    mean = sum;
    if (change < 1e-10) break;
  }
  ShapeModel m;
  m.ures_ = ures;
  m.vres_ = vres;
  m.mean_landmarks_ = mean;
  const Eigen::Index d = static_cast<Eigen::Index>(ures) * vres * 3;
  Eigen::MatrixXd X(d, n);
  for (int i = 0; i < n; ++i)
    X.col(i) = flat(transformed(surfaces[i], fit_similarity(landmarks[i], mean)));
  m.mean_ = X.rowwise().mean();
  X.colwise() -= m.mean_;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(X, Eigen::ComputeThinU);
  const Eigen::VectorXd var = svd.singularValues().array().square() / std::max(1, n - 1);
  const double total = var.sum();
  int k = 0;
  double kept = 0;
  while (k < var.size() && total > 0 && kept < variance_kept * total && var[k] > 1e-12 * total)
    kept += var[k++];
  m.basis_ = svd.matrixU().leftCols(k);
  m.sd_ = var.head(k).cwiseSqrt();
  return m;
}

Similarity ShapeModel::placement(const Points3& landmarks) const {
  return fit_similarity(mean_landmarks_, landmarks);
}

Points3 ShapeModel::place_mean(const Points3& landmarks) const {
  return transformed(unflat(mean_), placement(landmarks));
}

Points3 ShapeModel::constrain(const Points3& points, const Similarity& to_image, double limit_sd,
                              int max_modes) const {
  if (points.rows() != static_cast<Eigen::Index>(ures_) * vres_)
    throw Error("shape model: expected " + std::to_string(ures_ * vres_) + " points, got " +
                std::to_string(points.rows()));
  const Eigen::VectorXd x = flat(transformed(points, to_image.inverse())) - mean_;
  const int k = max_modes < 0 ? modes() : std::min(max_modes, modes());
  Eigen::VectorXd b = basis_.leftCols(k).transpose() * x;
  for (int i = 0; i < k; ++i) b[i] = std::clamp(b[i], -limit_sd * sd_[i], limit_sd * sd_[i]);
  return transformed(unflat(mean_ + basis_.leftCols(k) * b), to_image);
}

std::vector<double> ShapeModel::serialize() const {
  std::vector<double> v = {static_cast<double>(ures_), static_cast<double>(vres_),
                           static_cast<double>(mean_landmarks_.rows()),
                           static_cast<double>(modes())};
  v.insert(v.end(), mean_landmarks_.data(), mean_landmarks_.data() + mean_landmarks_.size());
  v.insert(v.end(), mean_.data(), mean_.data() + mean_.size());
  v.insert(v.end(), basis_.data(), basis_.data() + basis_.size());
  v.insert(v.end(), sd_.data(), sd_.data() + sd_.size());
  return v;
}

ShapeModel ShapeModel::deserialize(const std::vector<double>& v) {
  if (v.size() < 4) throw Error("shape model: truncated data");
  ShapeModel m;
  m.ures_ = static_cast<int>(v[0]);
  m.vres_ = static_cast<int>(v[1]);
  const auto nl = static_cast<Eigen::Index>(v[2]);
  const auto k = static_cast<Eigen::Index>(v[3]);
  const Eigen::Index d = static_cast<Eigen::Index>(m.ures_) * m.vres_ * 3;
  if (m.ures_ < 3 || m.vres_ < 2 || nl < 3 || k < 0 ||
      v.size() != static_cast<std::size_t>(4 + nl * 3 + d + d * k + k))
    throw Error("shape model: data of the wrong size");
  std::size_t o = 4;
  m.mean_landmarks_ = Eigen::Map<const Points3>(v.data() + o, nl, 3);
  o += static_cast<std::size_t>(nl * 3);
  m.mean_ = Eigen::Map<const Eigen::VectorXd>(v.data() + o, d);
  o += static_cast<std::size_t>(d);
  m.basis_ = Eigen::Map<const Eigen::MatrixXd>(v.data() + o, d, k);
  o += static_cast<std::size_t>(d * k);
  m.sd_ = Eigen::Map<const Eigen::VectorXd>(v.data() + o, k);
  return m;
}

}  // namespace mvtwin::detection
