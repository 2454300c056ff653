#pragma once
#include <string>
#include <vector>

#include "mvtwin/core/annulus_plane.h"
#include "mvtwin/core/triangle_mesh.h"
#include "mvtwin/core/valve_parameters.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {

/// How the open valve is simulated and judged (docs/clip-devices.md, "The valve after the clip
/// opens"). The same for every patient.
struct DiastoleOptions {
  /// Transmitral pressure (atrium above ventricle) on the open leaflets, mmHg: the early
  /// diastolic peak gradient of a normal valve is a few mmHg.
  double transmitral_mmhg = 5.0;
  /// Mean diastolic flow for the gradient: stroke volume over the diastolic filling period
  /// (70 mL over 0.5 s: a resting adult at about 70 beats/min).
  double stroke_volume_ml = 70.0;
  double filling_time_s = 0.5;
  /// Stenosis: a valve area below this or a mean gradient at least this (ASE/EACVI: MVA < 1.5
  /// cm^2 is significant mitral stenosis; a mean gradient >= 5 mmHg after edge-to-edge repair
  /// commonly stops further clipping).
  double stenosis_mva_cm2 = 1.5;
  double stenosis_gradient_mmhg = 5.0;

  bool is_valid(std::string* error) const;
};

/// Mean transmitral gradient from the Gorlin relation with the mitral constant 37.7 (44.3 x
/// 0.85): MVA = Q / (37.7 sqrt(dP)), so dP = (Q / (37.7 MVA))^2; Q in mL/s, MVA in cm^2, mmHg.
double gorlin_mean_gradient_mmhg(double flow_ml_per_s, double mva_cm2);

/// The open valve with its clips.
struct DiastolicOpening {
  bool converged = false;
  std::string reason;
  /// The open frame the model rests in: the widest before end-diastole, or end-diastole when
  /// the clips' grasp on the widest failed (`fallback` then says why).
  int frame = -1;
  std::string fallback;
  /// Mitral valve area: the openings seen along the annulus normal (perpendicular to the
  /// inflow), summed, cm^2; each opening largest first. A clip device and the tissue it holds
  /// close what they cover (clip_device_footprint).
  double mva_cm2 = 0;
  std::vector<double> openings_cm2;
  double gradient_mmhg = 0;  ///< gorlin_mean_gradient_mmhg at the options' flow
  bool stenosis = false;
  ClosureResult result;  ///< the simulation (its last sample is the open valve)
};

/// What the clip devices of a result and the tissue they hold cover seen along `plane`'s normal:
/// per device, the convex hull in the plane of both leaflets' grasped nodes at the end
/// (ClipGrasp::anterior_band, posterior_band: the arms close the two bands on the device's body
/// between them), as a fan of triangles through those nodes whose projection is that hull.
/// Empty for clips without grasped bands (the paper's spring).
TriangleMesh clip_device_footprint(const ClosureResult& result, const AnnulusPlane& plane);

/// Simulates the valve open: the finite-element model built on the widest open frame up to
/// end-diastole (the leaflets rest open in diastole), the annulus and papillary tips held there
/// (their diastolic positions), the clips of `options` closed first as in a closure (pressure
/// off), then the transmitral pressure from the atrium, held until the valve is at rest. A
/// device grasps as deep as it would on the closing valve (its insertion from the closure's
/// geometry, ClipGrasp). Never throws for a numerical failure; throws mvtwin::Error for invalid
/// options or a sequence without an open frame with leaflets.
DiastolicOpening simulate_diastole(const ValveSequence& sequence, const ValveParameters& parameters,
                                   const ClosureOptions& options,
                                   const DiastoleOptions& diastole = {});

}  // namespace mvtwin::forward
