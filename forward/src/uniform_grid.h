#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

namespace mvtwin::forward {

/// Points binned in a dense grid of cubic cells over their bounding box (a counting sort), so
/// that the points of a cell are found in constant time. Used by the contact searches, which
/// ask for the points near each of a few thousand triangles.
///
/// The cell size is at least the one asked for, larger only when the box would need more than
/// kMaxCells cells (a run that has blown apart): cells then hold more points, never fewer, so a
/// box query still returns every point inside the box (and some outside it).
class UniformGrid {
 public:
  static constexpr std::int64_t kMaxCells = std::int64_t{1} << 22;

  /// position(i) for i in [0, count) gives the point's coordinates.
  template <typename Position>
  UniformGrid(int count, double cell, Position position) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(0.0), hi = lo;
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector3d p = position(i);
      lo = i == 0 ? p : Eigen::Vector3d(lo.cwiseMin(p));
      hi = i == 0 ? p : Eigen::Vector3d(hi.cwiseMax(p));
    }
    lo_ = lo;
    h_ = cell;
    const Eigen::Vector3d extent = hi - lo;
    if (extent.allFinite() && cell > 0) {
      auto cells_along = [&](double e) { return std::floor(e / h_) + 1.0; };
      while (cells_along(extent.x()) * cells_along(extent.y()) * cells_along(extent.z()) >
             static_cast<double>(kMaxCells))
        h_ *= 2.0;
      for (int k = 0; k < 3; ++k) n_[k] = static_cast<std::int64_t>(cells_along(extent[k]));
    } else {
      h_ = std::numeric_limits<double>::infinity();  // one cell holds every point
    }
    start_.assign(static_cast<size_t>(n_[0] * n_[1] * n_[2] + 1), 0);
    std::vector<std::int64_t> cell_of(static_cast<size_t>(count));
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector3d p = position(i);
      std::int64_t c[3];
      for (int k = 0; k < 3; ++k) c[k] = clamp_index(k, p[k]);
      cell_of[static_cast<size_t>(i)] = (c[0] * n_[1] + c[1]) * n_[2] + c[2];
      ++start_[static_cast<size_t>(cell_of[static_cast<size_t>(i)] + 1)];
    }
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(static_cast<size_t>(count));
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (int i = 0; i < count; ++i) items_[static_cast<size_t>(fill[cell_of[i]]++)] = i;
  }

  /// Calls visit(i) for every point in the cells that overlap the box [lo, hi], in increasing
  /// cell order and, within a cell, in increasing index.
  template <typename Visit>
  void for_each_near(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Visit visit) const {
    for_each_slots_near(lo, hi, [&](int first, int last) {
      for (int q = first; q < last; ++q) visit(items_[static_cast<size_t>(q)]);
    });
  }

  /// The same points as for_each_near, as ranges [first, last) of slots: slot q holds point
  /// items()[q]. A caller that copies what it needs of each point into slot order reads it
  /// contiguously (the contact search's hot loop).
  template <typename VisitSlots>
  void for_each_slots_near(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                           VisitSlots visit) const {
    std::int64_t a[3], b[3];
    for (int k = 0; k < 3; ++k) {
      if (hi[k] < lo_[k] || lo[k] > lo_[k] + static_cast<double>(n_[k]) * h_) return;  // outside
      a[k] = clamp_index(k, lo[k]);
      b[k] = clamp_index(k, hi[k]);
    }
    for (std::int64_t i = a[0]; i <= b[0]; ++i) {
      for (std::int64_t j = a[1]; j <= b[1]; ++j) {
        const std::int64_t row = (i * n_[1] + j) * n_[2];
        const int first = start_[static_cast<size_t>(row + a[2])];
        const int last = start_[static_cast<size_t>(row + b[2] + 1)];
        if (first < last) visit(first, last);
      }
    }
  }

  /// The points in slot order (by cell, then index).
  const std::vector<int>& items() const { return items_; }

 private:
  std::int64_t clamp_index(int k, double v) const {
    const double c = std::floor((v - lo_[k]) / h_);
    if (!(c > 0)) return 0;  // also NaN and the single infinite cell
    return std::min(static_cast<std::int64_t>(std::min(c, 1e15)), n_[k] - 1);
  }

  Eigen::Vector3d lo_;
  double h_ = 1.0;
  std::int64_t n_[3] = {1, 1, 1};
  std::vector<int> start_;  // per cell, the first of its points in items_ (+ one end)
  std::vector<int> items_;
};

}  // namespace mvtwin::forward
