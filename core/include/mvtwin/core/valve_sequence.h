#pragma once
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/landmark.h"
#include "mvtwin/core/leaflet_grid.h"

namespace mvtwin {

/// The valve at one time frame, in physical image space (mm).
struct ValveFrame {
  /// Time of the frame in s from the start of the sequence.
  double time_s = 0.0;
  /// Landmark positions in mm (storage order of Landmark); an entry that is not observed in
  /// this frame is NaN and has landmark_observed false.
  std::array<Eigen::Vector3d, kNumLandmarks> landmarks;
  std::array<bool, kNumLandmarks> landmark_observed{};
  /// True where a landmark that is present (landmark_observed) was not seen in the images but
  /// estimated from published anatomy (an imported patient's papillary tips, for example).
  /// Every report that uses it says so.
  std::array<bool, kNumLandmarks> landmark_assumed{};
  /// The annulus curve: ures by 3, the v = 0 row of the grid. Always present, because the
  /// annulus motion is a boundary condition even in frames whose leaflets are not observed.
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> annulus;
  /// The LA leaflet surface; empty when this frame's leaflets are not observed (for a virtual
  /// patient: closed frames that only the simulator can produce).
  std::optional<LeafletGrid> la_surface;

  Eigen::Vector3d landmark(Landmark l) const { return landmarks[index(l)]; }
  bool observed(Landmark l) const { return landmark_observed[index(l)]; }
  bool assumed(Landmark l) const { return landmark_assumed[index(l)]; }
};

/// A valve over time: what detection produces and what the forward model consumes
/// (Mansi et al. 2012, Sec. 2.1).
/// A torn stretch of marginal chordae (anatomy that the images show: a flail segment). The
/// marginal chordae that insert at grid coordinate s in [s_begin, s_end) around the annulus
/// (from the anterolateral commissure, anterior leaflet for s < 0.5; valve-model.md) are
/// ruptured, whatever number of chordae the model has.
struct ChordaeRupture {
  double s_begin = 0.0, s_end = 0.0;
  bool contains(double s) const { return s >= s_begin && s < s_end; }
  /// 0 <= s_begin < s_end <= 1.
  bool is_valid() const { return s_begin >= 0.0 && s_begin < s_end && s_end <= 1.0; }
};

/// The stretch around marginal chorda k of n evenly spaced ones (insertion site s = k / n):
/// [(k - 1/2) / n, (k + 1/2) / n), clipped to [0, 1].
ChordaeRupture marginal_chorda_rupture(int k, int n);

/// The length of the marginal chorda inserting at grid coordinate s (as for ChordaeRupture),
/// from its insertion on the free edge to the papillary tip on its side: anatomy that the images
/// can show (chordae are measured on 3D echo and CT, Kavitha et al. 2014). Where a sequence has
/// them the model's marginal rest lengths start from them instead of the end-diastolic
/// insertion-to-tip distance (docs/valve-model.md).
struct ChordaLength {
  double s = 0.0;          ///< insertion site, 0 <= s < 1
  double length_mm = 0.0;  ///< > 0
};

struct ValveSequence {
  int ures = 0;
  int vres = 0;
  std::vector<ValveFrame> frames;
  /// Index of the end-diastolic frame (last fully open), or -1 if unknown.
  int end_diastole = -1;
  /// Index of the first closed frame, or -1 if unknown.
  int first_closed = -1;
  /// Ruptured marginal chordae (none for most valves).
  std::vector<ChordaeRupture> ruptured_chordae;
  /// Marginal chordae lengths (increasing s; none for most valves: the model then starts from
  /// the end-diastolic distances, Mansi et al. 2012).
  std::vector<ChordaLength> marginal_chordae_lengths;

  /// The marginal chorda length at site s, interpolated linearly between the sites around the
  /// (periodic) annulus; NaN when the sequence has none.
  double marginal_chorda_length_at(double s) const;
  /// What is wrong with the marginal chordae lengths (sites not increasing in [0, 1), a length
  /// that is not positive and finite), "" when nothing.
  std::string chordae_lengths_problem() const;

  int num_frames() const { return static_cast<int>(frames.size()); }
  /// Whether the first closed frame has its leaflets (observed, or simulated by
  /// --simulate-closure / a study's observation); false when it is unknown.
  bool has_closed_leaflets() const {
    return first_closed >= 0 && frames[static_cast<size_t>(first_closed)].la_surface.has_value();
  }
  /// Names of the landmarks assumed (estimated from anatomy) in any frame, "" when none.
  std::string assumed_landmarks() const;

  /// Throws mvtwin::Error naming `what` and the first problem: inconsistent resolutions or
  /// shapes, non-finite coordinates, times not strictly increasing, phase indices out of
  /// range or out of order, observed landmarks that are NaN, an annulus that differs from the
  /// v = 0 row of the surface, a rupture outside 0 <= s_begin < s_end <= 1, chordae lengths
  /// that are not positive or whose sites are not increasing in [0, 1).
  void validate(const char* what) const;

  /// Copies the chordae anatomy that detection from images does not find (torn chordae, the
  /// marginal chordae's lengths) from `known` where this sequence has none.
  void keep_chordae_anatomy(const ValveSequence& known);

  /// The same sequence on another (ures, vres) grid; correspondence is kept (the annulus is
  /// resampled with the same periodic spline as the surface's v = 0 row).
  ValveSequence resampled(int ures, int vres) const;
};

/// Resamples a closed annulus curve (n by 3, periodic) to m points by periodic Catmull-Rom.
Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> resample_closed_curve(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& curve,
    int m);

}  // namespace mvtwin
