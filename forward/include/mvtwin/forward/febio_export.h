#pragma once
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "mvtwin/forward/closure_scene.h"
#include "mvtwin/forward/closure_simulation.h"

namespace mvtwin::forward {

/// Writes the closure scene as an FEBio input file (febio_spec 4.0, docs/febio-export.md), so
/// that FEBio, the field's open solver, can run the same scene:
///   - the leaflets' quadratic (tet10) or linear (tet4) tetrahedra in two domains, anterior and
///     posterior, each a "neo-Hookean transiso" material (FEBio's compressible transversely
///     isotropic neo-Hookean: Ez = E_fibre, Ep = E_cross, vz = nu12, vp = nu23, gz = G12),
///     which linearizes to mvtwin's stiffness and, unlike St Venant-Kirchhoff ("orthotropic
///     elastic"), neither softens in compression nor lets an element collapse, and a
///     per-element material axis (a = the fibre, the material's symmetry axis); with Rayleigh
///     damping, wrapped in a Maxwell branch ("viscoelastic", g1 = 1, t1 = alpha_K) that stands
///     for mvtwin's stiffness-proportional damping, and the load held kFebioRelaxTimes x
///     alpha_K after the closure (a second analysis step) for it to relax (without it FEBio's
///     quasi-static path met the slack, unstable membranes of functional MR early in the closure
///     and stopped there: docs/febio-export.md);
///   - each chorda as "nonlinear spring"s from every node of its insertion cross-section to a
///     node at its papillary tip (febio_chorda_springs), with the continuous bilinear,
///     tension-only law as a force-elongation curve that accounts for the rest length;
///   - clips as tension-only linear springs (FEBio has no clip phase: their rest length is the
///     target from the start);
///   - the annulus nodes and papillary tips as prescribed displacements, one load curve per
///     node and axis, sampled from the same C1 interpolation of the image frames;
///   - the follower pressure on the ventricular surface (tri6 / tri3 facets) with the same
///     smoothstep profile;
///   - leaflet contact as FEBio's frictionless "contact potential" (febio_contact_potential)
///     between the anterior and the posterior leaflet's surfaces and rims (rim_faces);
///   - nodes numbered for a small profile (febio_node_order; the node set `mvtwin_order` maps
///     them back), an automatic time stepper with retries.
/// Units are mvtwin's (mm, s, N, MPa, t). What FEBio cannot express is said in the file's
/// header comment: the mass-proportional damping (the analysis is quasi-static), self-contact
/// within one leaflet, the contact wall law and the inversion guard. `comment` (provenance) is
/// written at the top. Written atomically; throws mvtwin::Error if it cannot be written. The
/// force-elongation curve of a tension-only spring for FEBio's "nonlinear spring" (measure
/// "elongation", extrapolated linearly): elongation DL from the reference length `initial`
/// (mm) against force (N), so that a spring of rest length `rest` follows `law` (a clip: law
/// null, linear stiffness k N/mm).
std::vector<std::pair<double, double>> febio_spring_curve(double initial, double rest,
                                                          const ChordaLaw* law, double k);

/// FEBio's "contact potential" (FEBioMech/FEContactPotential.cpp) between the two leaflets: a
/// repulsion f(r) between integration points of the two surfaces, weighted by both areas,
/// f = c1 (r - R_out)^2 for R_in <= r < R_out and kc / r^p - c2 closer (a wall). Between two
/// parallel surfaces at gap g it gives the pressure 2 pi g int_g^R_out f(r) dr.
///   - mvtwin's penalty with its distances scaled by kFebioContactRangeFactor: R_in = 2 x the
///     contact distance, R_out = 2 x the alarm distance, and the pressure k (R_out - R_in) at
///     R_in, with mvtwin's stiffness per area k.
///   - Why not mvtwin's own distances (written before): the potential acts between points, not
///     surfaces. With R_out = the alarm distance (0.6 mm), about the spacing of the integration
///     points at the paper's grid, FEBio's static solve stalled once the leaflets touched
///     (virtual patients 1 and 3, issue 16); with twice the range patient 1 ran to the end.
///   - The cost: the leaflets coapt farther apart. gap_at_peak is where the pressure equals the
///     peak pressure (0.86 mm at the defaults, against mvtwin's 0.45 mm).
struct FebioContactPotential {
  double kc = 0, p = 4, r_in = 0, r_out = 0;
  double gap_at_peak = 0;         ///< gap between flat surfaces at the peak pressure, mm
  double mvtwin_gap_at_peak = 0;  ///< the same for mvtwin's penalty: k (d_a - g) = p, mm
  /// Surface points closer than this in the reference configuration never pair (mvtwin's
  /// neighbour exclusion). FEBio 4 compares it with the squared reference distance, so this is
  /// exclusion_mm^2 (mm^2).
  double r0_min = 0;
};
inline constexpr double kFebioContactRangeFactor = 2.0;
/// After the closure, the load is held in a second analysis step ("relax") for this many of
/// the leaflets' Maxwell relaxation times t1 (write_febio: mvtwin's stiffness-proportional
/// damping as a viscoelastic branch), in kFebioRelaxSteps steps. Long enough for the soft modes
/// too: under a branch of stiffness K and a mode of stiffness K_soft the mode creeps with the
/// time constant t1 (1 + K / K_soft), about 1.7 s on virtual patient 1's creeping mode
/// (docs/forward-status.md), so a hold of 10 t1 (1 s) left it half-way.
inline constexpr double kFebioRelaxTimes = 100.0;
inline constexpr int kFebioRelaxSteps = 40;
FebioContactPotential febio_contact_potential(const SelfContactOptions& contact,
                                              double stiffness_per_area, double peak_pressure_mpa);

/// One spring of a chorda in FEBio: from a node of its insertion cross-section to its papillary
/// tip. Each of the cross-section's k nodes gets one spring of force share 1/k whose force curve
/// (febio_spring_curve(mean_length, rest, ...)) reads the elongation from the node's own
/// end-diastolic length as the mean point's: while the cross-section moves without rotating, the
/// springs together pull exactly as mvtwin's chorda does from the mean point.
struct FebioChordaSpring {
  int node = 0;            ///< mvtwin node (0-based)
  double scale = 1;        ///< share of the force
  double initial = 0;      ///< node to tip at end-diastole, mm (FEBio's reference length)
  double mean_length = 0;  ///< the cross-section's mean point to the tip at end-diastole, mm
  double rest = 0;         ///< the chorda's rest length, mm
};
std::vector<FebioChordaSpring> febio_chorda_springs(const ClosureScene& scene, int chorda);

/// Node numbering for FEBio: reverse Cuthill-McKee on the elements' node graph, so that the
/// skyline solver's profile stays small. order[k] is the mvtwin node numbered k + 1.
std::vector<int> febio_node_order(const SolidMesh& mesh);

/// The boundary faces of the leaflets' elements that are neither atrial nor ventricular nor
/// held (annulus): the free edge and the commissural sides, as corner triples oriented outward,
/// with the leaflet (0 anterior, 1 posterior).
struct RimFace {
  int a, b, c, leaflet;
};
std::vector<RimFace> rim_faces(const ClosureScene& scene);

/// The log file FEBio writes beside valve.feb: at every converged step, one line per node of
/// mvtwin's model in mvtwin's order (node set mvtwin_order), "FEBio-id x y z" in mm.
inline constexpr const char* kFebioNodeLog = "febio_nodes.txt";

/// `guarded`: elements mvtwin's inversion guard held (ClosureResult::guarded_elements), written as
/// isotropic compressible neo-Hookean (E = the leaflet's cross-fibre modulus, v = its Poisson
/// ratio) in domains of their own. (Written when the leaflets were St Venant-Kirchhoff, which
/// lets such elements collapse; the leaflets' law now resists collapse itself.)
void write_febio(const std::filesystem::path& path, const ClosureScene& scene,
                 const ClosureOptions& options, const std::string& comment,
                 const std::vector<int>& guarded = {});

}  // namespace mvtwin::forward
