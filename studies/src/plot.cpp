#include "mvtwin/studies/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "png_file.h"

namespace mvtwin::studies {
namespace {

// A colour-blind-safe palette (Okabe-Ito), BGR.
const cv::Scalar kPalette[] = {{178, 114, 0},   {0, 159, 230},  {115, 158, 0},  {0, 94, 213},
                               {167, 121, 204}, {233, 180, 86}, {66, 228, 240}, {0, 0, 0}};
const int kFont = cv::FONT_HERSHEY_SIMPLEX;

std::string tick_text(double v) {
  char s[32];
  const double a = std::abs(v);
  if (v == 0) return "0";
  if (a >= 1e4 || a < 1e-3)
    std::snprintf(s, sizeof s, "%.0e", v);
  else if (a >= 100 || std::abs(v - std::round(v)) < 1e-9)
    std::snprintf(s, sizeof s, "%.0f", v);
  else if (a >= 1)
    std::snprintf(s, sizeof s, "%.3g", v);
  else
    std::snprintf(s, sizeof s, "%.2g", v);
  return s;
}

/// "Nice" linear ticks covering [lo, hi].
std::vector<double> linear_ticks(double lo, double hi) {
  const double span = hi - lo;
  const double raw = span / 5;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  std::vector<double> t;
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step)
    t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  return t;
}

struct Axis {
  double lo = 0, hi = 1;
  bool log = false;
  double map(double v) const {  // to [0, 1]
    if (log) return (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
    return (v - lo) / (hi - lo);
  }
  std::vector<double> ticks() const {
    if (!log) return linear_ticks(lo, hi);
    std::vector<double> t;
    for (double e = std::floor(std::log10(lo)); e <= std::ceil(std::log10(hi)); ++e) {
      const double v = std::pow(10.0, e);
      if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) t.push_back(v);
    }
    if (t.size() < 2) {  // less than a decade: 1-2-5
      t.clear();
      for (double e = std::floor(std::log10(lo)); e <= std::ceil(std::log10(hi)); ++e)
        for (double m : {1.0, 2.0, 5.0}) {
          const double v = m * std::pow(10.0, e);
          if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) t.push_back(v);
        }
    }
    return t;
  }
};

Axis make_axis(std::vector<double> v, bool log, bool from_zero) {
  Axis a;
  a.log = log;
  v.erase(std::remove_if(v.begin(), v.end(),
                         [&](double x) { return !std::isfinite(x) || (log && x <= 0); }),
          v.end());
  if (v.empty()) {
    a.lo = log ? 0.1 : 0;
    a.hi = 1;
    return a;
  }
  double lo = *std::min_element(v.begin(), v.end()), hi = *std::max_element(v.begin(), v.end());
  if (log) {
    if (hi <= lo) hi = lo * 10;
    a.lo = std::pow(10.0, std::floor(std::log10(lo) * 4) / 4);
    a.hi = std::pow(10.0, std::ceil(std::log10(hi) * 4) / 4);
    if (a.hi <= a.lo) a.hi = a.lo * 10;
    return a;
  }
  if (from_zero) lo = std::min(lo, 0.0);
  if (hi <= lo) {
    hi = lo + (lo == 0 ? 1 : std::abs(lo) * 0.1);
  }
  const double pad = 0.05 * (hi - lo);
  a.lo = (from_zero && lo >= 0) ? lo : lo - pad;
  a.hi = hi + pad;
  return a;
}

/// OpenCV's Hershey fonts draw ASCII only: the few non-ASCII signs labels use, spelled out.
std::string ascii(std::string s) {
  const std::pair<const char*, const char*> subs[] = {
      {"\u00b1", "+/-"}, {"\u00b2", "^2"}, {"\u00b3", "^3"}, {"\u2192", "->"}, {"\u2264", "<="},
      {"\u2265", ">="},  {"\u00b5", "u"},  {"\u2013", "-"},  {"\u2014", "-"},  {"\u00d7", "x"}};
  for (const auto& [from, to] : subs)
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at))
      s.replace(at, std::strlen(from), to);
  for (char& c : s)
    if (static_cast<unsigned char>(c) >= 0x80) c = '?';
  return s;
}

void text(cv::Mat& img, const std::string& raw, cv::Point at, double scale, int align /*-1 0 1*/,
          int thickness = 1) {
  const std::string s = ascii(raw);
  int base = 0;
  const cv::Size sz = cv::getTextSize(s, kFont, scale, thickness, &base);
  at.x -= align == 0 ? sz.width / 2 : align > 0 ? sz.width : 0;
  cv::putText(img, s, at, kFont, scale, cv::Scalar(30, 30, 30), thickness, cv::LINE_AA);
}

void dashed(cv::Mat& img, cv::Point a, cv::Point b, cv::Scalar c) {
  const double len = std::hypot(b.x - a.x, b.y - a.y);
  for (double s = 0; s < len; s += 12) {
    const double e = std::min(len, s + 7);
    cv::line(img, a + (b - a) * (s / len), a + (b - a) * (e / len), c, 1, cv::LINE_AA);
  }
}

}  // namespace

void Plot::write_png(const std::filesystem::path& path) const {
  if (series.empty()) throw Error(path.string() + ": a plot without data");
  const bool bars = !categories.empty();
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 90, right = 30, top = 50, bottom = 80;
  const int legend_h = 22 * static_cast<int>(series.size() > 1 ? (series.size() + 1) / 2 : 0);
  const cv::Rect box(left, top + legend_h, width - left - right, height - top - bottom - legend_h);

  std::vector<double> xs, ys;
  for (const auto& s : series) {
    xs.insert(xs.end(), s.x.begin(), s.x.end());
    for (std::size_t i = 0; i < s.y.size(); ++i) {
      ys.push_back(s.y[i]);
      if (i < s.y_error.size()) {
        ys.push_back(s.y[i] + s.y_error[i]);
        ys.push_back(s.y[i] - s.y_error[i]);
      }
    }
  }
  for (const auto& [v, l] : h_lines) ys.push_back(v);
  Axis ax = bars ? Axis{-0.5, static_cast<double>(categories.size()) - 0.5, false}
                 : make_axis(xs, log_x, false);
  Axis ay = make_axis(ys, log_y, bars);
  auto px = [&](double x, double y) {
    return cv::Point(box.x + static_cast<int>(std::lround(ax.map(x) * box.width)),
                     box.y + box.height - static_cast<int>(std::lround(ay.map(y) * box.height)));
  };

  // Grid, ticks and labels.
  for (double t : ay.ticks()) {
    const cv::Point p = px(ax.lo, t);
    cv::line(img, p, {box.x + box.width, p.y}, cv::Scalar(230, 230, 230), 1);
    text(img, tick_text(t), {box.x - 8, p.y + 5}, 0.45, 1);
  }
  if (bars) {
    const double slot = 0.95 * box.width / static_cast<double>(categories.size());
    for (std::size_t i = 0; i < categories.size(); ++i) {
      // Shrink a label until it fits its slot (no overlapping names).
      double scale = 0.45;
      int base = 0;
      while (scale > 0.25 && cv::getTextSize(categories[i], kFont, scale, 1, &base).width > slot)
        scale -= 0.02;
      text(img, categories[i], {px(static_cast<double>(i), ay.lo).x, box.y + box.height + 20},
           scale, 0);
    }
  } else {
    for (double t : ax.ticks()) {
      const cv::Point p = px(t, ay.lo);
      cv::line(img, {p.x, box.y}, p, cv::Scalar(230, 230, 230), 1);
      text(img, tick_text(t), {p.x, box.y + box.height + 20}, 0.45, 0);
    }
  }
  cv::rectangle(img, box, cv::Scalar(60, 60, 60), 1);
  text(img, title, {width / 2, 30}, 0.65, 0, 2);
  text(img, x_label, {box.x + box.width / 2, height - 25}, 0.5, 0);
  {  // y label, rotated
    int base = 0;
    const std::string y_text = ascii(y_label);
    const cv::Size sz = cv::getTextSize(y_text, kFont, 0.5, 1, &base);
    cv::Mat t(sz.height + base + 4, sz.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(t, y_text, {2, sz.height + 1}, kFont, 0.5, cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
    cv::Mat r;
    cv::rotate(t, r, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int y0 = std::max(0, box.y + box.height / 2 - r.rows / 2);
    if (y0 + r.rows <= height && 10 + r.cols <= width)
      r.copyTo(img(cv::Rect(10, y0, r.cols, r.rows)));
  }
  for (const auto& [v, l] : h_lines)
    dashed(img, px(ax.lo, v), px(ax.hi, v), cv::Scalar(80, 80, 80));

  // Data.
  const int ns = static_cast<int>(series.size());
  for (int k = 0; k < ns; ++k) {
    const PlotSeries& s = series[static_cast<std::size_t>(k)];
    const cv::Scalar c = kPalette[k % 8];
    if (bars) {
      const double w = 0.8 / ns;
      for (std::size_t i = 0; i < s.y.size() && i < categories.size(); ++i) {
        if (!std::isfinite(s.y[i])) continue;
        const double x0 = static_cast<double>(i) - 0.4 + w * k;
        cv::rectangle(img, px(x0 + 0.1 * w, std::max(0.0, ay.lo)), px(x0 + 0.9 * w, s.y[i]), c,
                      cv::FILLED);
        if (i < s.y_error.size() && std::isfinite(s.y_error[i])) {
          const double xm = x0 + 0.5 * w;
          cv::line(img, px(xm, s.y[i] - s.y_error[i]), px(xm, s.y[i] + s.y_error[i]),
                   cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
        }
      }
      continue;
    }
    std::vector<cv::Point> pts;
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (log_x && s.x[i] <= 0) ||
          (log_y && s.y[i] <= 0))
        continue;
      pts.push_back(px(s.x[i], s.y[i]));
      if (i < s.y_error.size() && std::isfinite(s.y_error[i])) {
        const double lo = log_y ? std::max(s.y[i] - s.y_error[i], ay.lo) : s.y[i] - s.y_error[i];
        cv::line(img, px(s.x[i], lo), px(s.x[i], s.y[i] + s.y_error[i]), c, 1, cv::LINE_AA);
      }
    }
    if (s.line && pts.size() > 1) cv::polylines(img, pts, false, c, 2, cv::LINE_AA);
    if (s.markers)
      for (const auto& p : pts) cv::circle(img, p, 4, c, cv::FILLED, cv::LINE_AA);
  }
  // The reference lines' labels over the data, on a white ground (bars would hide them).
  for (const auto& [v, l] : h_lines) {
    const cv::Point b = px(ax.hi, v);
    int base = 0;
    const cv::Size sz = cv::getTextSize(ascii(l), kFont, 0.42, 1, &base);
    cv::rectangle(img, {b.x - 8 - sz.width, b.y - 8 - sz.height}, {b.x - 4, b.y - 3},
                  cv::Scalar(255, 255, 255), cv::FILLED);
    text(img, l, {b.x - 6, b.y - 6}, 0.42, 1);
  }
  // Legend, two columns above the box.
  if (ns > 1 || !series.front().name.empty()) {
    for (int k = 0; k < ns; ++k) {
      const int col = k % 2, row = k / 2;
      const cv::Point at(left + 10 + col * (box.width / 2), top + 14 + 22 * row);
      cv::rectangle(img, {at.x, at.y - 10}, {at.x + 22, at.y + 2}, kPalette[k % 8], cv::FILLED);
      text(img, series[static_cast<std::size_t>(k)].name, {at.x + 30, at.y + 1}, 0.45, -1);
    }
  }
  studies::write_png(path, img);
}

}  // namespace mvtwin::studies
