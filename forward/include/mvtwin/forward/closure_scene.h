#pragma once
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/chorda.h"
#include "mvtwin/forward/clip_device.h"
#include "mvtwin/forward/transversely_isotropic.h"
#include "mvtwin/forward/valve_model.h"

namespace mvtwin::forward {

struct ClosureOptions;

/// A chorda of the scene: its insertion point is the mean of `nodes` (the leaflet's
/// cross-section at the site), its other end a papillary tip.
struct SceneChorda {
  std::vector<int> nodes;
  int tip = 0;               ///< 0 anterolateral, 1 posteromedial
  double rest_length = 0.0;  ///< mm (end-diastolic length, or the anatomy's marginal chorda length,
                             ///< x the group's factor)
  ChordaLaw law;
  ChordaeGroup group = ChordaeGroup::kAnterolateralMarginal;
  bool marginal = true;
};

/// A two-point spring between the mean points of two node sets (a MitraClip, Mansi et al. 2012,
/// Sec. 2.4, or one tie of a clip device).
struct SceneSpring {
  std::vector<int> a, b;
  double stiffness = 0.0;    ///< N/mm
  double rest_length = 0.0;  ///< mm
  int clip = 0;              ///< the clip it belongs to
  bool bilateral = false;    ///< pushes as well as pulls (a device's ties); else tension only
};

/// A node whose motion is prescribed: it follows the mean displacement of annulus columns ua
/// and ub (equal for a corner node; the edge's ends for a mid-edge node).
struct PrescribedNode {
  int node, ua, ub;
};

/// A triangle of the ventricular surface where the pressure acts, and the nodes that carry its
/// consistent load (corners for linear elements, mid-edge nodes for quadratic ones: a uniform
/// pressure on a 6-node triangle puts nothing on its corners).
struct PressureFace {
  int a, b, c;
  int load[3];
};

/// Everything a closure simulation applies to the FE model besides the elements: chordae,
/// prescribed annulus and papillary motion over the simulated time, the pressure and its
/// profile, clip springs. Built once from a sequence, the patient's parameters and the options,
/// and shared by the simulator and the model export (VTK, FEBio), so that another solver can
/// run the same scene.
class ClosureScene {
 public:
  ValveModel model;
  std::vector<TransverselyIsotropic> leaflet_material;  ///< [0] anterior, [1] posterior
  std::vector<SceneChorda> chordae;
  std::vector<SceneSpring> springs;
  std::vector<ClipGrasp> grasps;  ///< per clip
  std::vector<PrescribedNode> prescribed;
  std::vector<PressureFace> pressure_faces;
  double peak_pressure_mpa = 0.0;

  /// Simulated duration (stretch x observed closure), s.
  double duration() const { return duration_; }
  /// Observed (image sequence) time of simulated time tau.
  double observed_time(double tau) const;
  /// Pressure at simulated time tau, MPa: 0 -> peak over the closure, a C1 smoothstep.
  double pressure(double tau) const;
  /// Papillary tip k (0 anterolateral, 1 posteromedial) at simulated time tau, mm.
  Eigen::Vector3d papillary_tip(int k, double tau) const;
  /// A landmark at simulated time tau (held at end-diastole when its motion is switched off).
  Eigen::Vector3d landmark(Landmark l, double tau) const;
  bool observed_at_end_diastole(Landmark l) const;
  /// The annulus curve (ures points) at simulated time tau.
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> annulus(double tau) const;
  /// Writes the prescribed nodes' positions at simulated time tau into x (all nodes, flattened).
  void prescribed_positions(double tau, Eigen::VectorXd* x) const;

 private:
  friend ClosureScene make_closure_scene(const ValveSequence&, const ValveParameters&,
                                         const ClosureOptions&);
  void weights(double t, int* f, Eigen::Vector4d* w) const;
  int clamp_frame(int i) const;

  ValveSequence sequence_;
  double stretch_ = 10.0, duration_ = 0.0;
  bool annulus_motion_ = true, papillary_motion_ = true;
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> annulus_;  // per frame
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> annulus_ed_;
};

/// How deep each leaflet inserts into a device's arm (anterior, posterior), mm: the leaflets span
/// the annulus chord between the sites at the first closed frame to their meeting point in
/// proportion to their lengths at end-diastole, L (L + Lp - chord) / (L + Lp), capped by the arm;
/// an insertion given in the options is taken as it is (capped by the arm).
std::pair<double, double> clip_insertion_mm(const ValveSequence& sequence, const ClipOptions& clip);

/// Adds clip `index` of the options, a device (ClipOptions::width_mm > 0), to the scene: its
/// grasped bands, ties and ClipGrasp. Throws mvtwin::Error when a leaflet has no tissue within
/// the device's reach.
void add_device_clip(const ValveSequence& sequence, const ClosureOptions& options, int index,
                     ClosureScene* scene);

/// Builds the scene. Throws mvtwin::Error for invalid options, a sequence without an
/// end-diastolic frame before a first closed one, or a model that cannot be built.
ClosureScene make_closure_scene(const ValveSequence& sequence, const ValveParameters& parameters,
                                const ClosureOptions& options);

}  // namespace mvtwin::forward
