#include "mvtwin/studies/en_face.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvtwin/core/error.h"
#include "png_file.h"

namespace mvtwin::studies {

double write_en_face_png(const std::filesystem::path& path, const LeafletGrid& g,
                         const EnFaceView& view) {
  const int U = g.ures(), V = g.vres();
  const auto& P = g.points();
  auto at = [&](int u, int v) -> Eigen::Vector3d {
    return P.row(static_cast<Eigen::Index>(v) * U + ((u % U) + U) % U).transpose();
  };
  // The annulus (row 0): its centroid and Newell normal. u runs clockwise seen from the atrium,
  // so the Newell normal points into the ventricle: the direction the camera looks.
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), d = Eigen::Vector3d::Zero();
  for (int u = 0; u < U; ++u) c += at(u, 0);
  c /= U;
  for (int u = 0; u < U; ++u) d += (at(u, 0) - c).cross(at(u + 1, 0) - c);
  if (!(d.norm() > 1e-9) || !P.allFinite())
    throw Error(path.string() + ": the valve's annulus has no area to draw");
  d.normalize();
  // Up: towards the anterior annulus' middle (u = U / 4); right = forward x up.
  Eigen::Vector3d up = at(U / 4, 0) - c;
  up -= up.dot(d) * d;
  if (!(up.norm() > 1e-9)) up = d.unitOrthogonal();
  up.normalize();
  const Eigen::Vector3d right = d.cross(up);
  double extent = 1.0;
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    const Eigen::Vector3d q = P.row(i).transpose() - c;
    extent = std::max({extent, std::abs(q.dot(right)), std::abs(q.dot(up))});
  }
  const int S = std::max(200, view.size_px), top = 22 + 18 * static_cast<int>(view.lines.size());
  const double scale = 0.42 * S / extent;  // px per mm
  const cv::Point2d mid(0.5 * S, top + 0.5 * S);
  auto px = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = p - c;
    return cv::Point(static_cast<int>(std::lround(mid.x + scale * q.dot(right))),
                     static_cast<int>(std::lround(mid.y - scale * q.dot(up))));
  };
  cv::Mat img(top + S, S, CV_8UC3, cv::Scalar(255, 255, 255));
  // The annulus' opening, dark red: what no leaflet covers is open to the flow.
  std::vector<cv::Point> ring;
  for (int u = 0; u < U; ++u) ring.push_back(px(at(u, 0)));
  cv::fillPoly(img, std::vector<std::vector<cv::Point>>{ring},
               cv::Scalar(kEnFaceOpenBgr[0], kEnFaceOpenBgr[1], kEnFaceOpenBgr[2]));
  // The leaflets' quads, farthest from the camera first (painter's order).
  struct Quad {
    double depth;
    int u, v;
  };
  std::vector<Quad> quads;
  for (int v = 0; v + 1 < V; ++v)
    for (int u = 0; u < U; ++u) {
      const double depth =
          (at(u, v) + at(u + 1, v) + at(u, v + 1) + at(u + 1, v + 1) - 4 * c).dot(d);
      quads.push_back({depth, u, v});
    }
  std::sort(quads.begin(), quads.end(),
            [](const Quad& a, const Quad& b) { return a.depth > b.depth; });
  for (const Quad& q : quads) {
    const bool anterior = g.column_tag(q.u) == LeafletTag::kAnterior;
    // Lighter towards the atrium: the depth along the view as shade.
    const double t = std::clamp(1.0 - 0.25 * q.depth / (0.8 * extent), 0.0, 1.0);
    const cv::Scalar base = anterior ? cv::Scalar(200, 150, 80) : cv::Scalar(80, 160, 220);
    const cv::Scalar col = base * (0.6 + 0.4 * t);
    std::vector<cv::Point> poly{px(at(q.u, q.v)), px(at(q.u + 1, q.v)), px(at(q.u + 1, q.v + 1)),
                                px(at(q.u, q.v + 1))};
    cv::fillConvexPoly(img, poly, col, cv::LINE_AA);
    cv::polylines(img, poly, true, col * 0.8, 1, cv::LINE_AA);
  }
  cv::polylines(img, ring, true, cv::Scalar(60, 60, 60), 2, cv::LINE_AA);
  // Free-edge point at a position along the coaptation line (the anterior leaflet's column).
  auto edge_at = [&](double pos, bool anterior) {
    const double s = anterior ? 0.5 * pos : 1.0 - 0.5 * pos;
    const double x = s * U;
    const int u0 = static_cast<int>(std::floor(x));
    const double f = x - u0;
    return px((1 - f) * at(u0, V - 1) + f * at(u0 + 1, V - 1));
  };
  for (const auto& [b, e] : view.openings) {
    for (double p = b; p <= e + 1e-9; p += 0.01) {
      cv::circle(img, edge_at(p, true), 3, cv::Scalar(0, 0, 230), cv::FILLED, cv::LINE_AA);
      cv::circle(img, edge_at(p, false), 3, cv::Scalar(0, 0, 230), cv::FILLED, cv::LINE_AA);
    }
  }
  for (double p : view.clips) {
    const cv::Point a = edge_at(p, true), b = edge_at(p, false);
    cv::line(img, a, b, cv::Scalar(20, 20, 20), 7, cv::LINE_AA);
    cv::circle(img, (a + b) / 2, 6, cv::Scalar(20, 20, 20), cv::FILLED, cv::LINE_AA);
  }
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  cv::putText(img, view.title, {10, 18}, font, 0.55, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  for (size_t i = 0; i < view.lines.size(); ++i)
    cv::putText(img, view.lines[i], {10, 38 + 18 * static_cast<int>(i)}, font, 0.45,
                cv::Scalar(40, 40, 40), 1, cv::LINE_AA);
  cv::putText(img, "A", px(c + 1.12 * (at(U / 4, 0) - c)) + cv::Point(-6, 6), font, 0.6,
              cv::Scalar(120, 60, 0), 2, cv::LINE_AA);
  cv::putText(img, "P", px(c + 1.12 * (at(3 * U / 4, 0) - c)) + cv::Point(-6, 6), font, 0.6,
              cv::Scalar(0, 80, 160), 2, cv::LINE_AA);
  // Scale bar: 10 mm.
  const int bar = static_cast<int>(std::lround(10.0 * scale));
  const cv::Point b0(S - 20 - bar, top + S - 20);
  cv::line(img, b0, b0 + cv::Point(bar, 0), cv::Scalar(0, 0, 0), 3);
  cv::putText(img, "10 mm", b0 + cv::Point(0, -8), font, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, "seen from the atrium; dark red: open", {10, top + S - 12}, font, 0.4,
              cv::Scalar(80, 80, 80), 1, cv::LINE_AA);
  studies::write_png(path, img);
  return scale;
}

}  // namespace mvtwin::studies
