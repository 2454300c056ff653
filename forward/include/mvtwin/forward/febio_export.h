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
///     posterior, each an "orthotropic elastic" material with the transversely isotropic
///     constants (E1 = E_fibre, E2 = E3 = E_cross, G12 = G31, G23 = E2 / (2 (1 + nu23)),
///     v12 = v23 = nu, v31 = nu E3 / E1) and a per-element material axis (a = the fibre);
///   - each chorda as a "nonlinear spring" from its insertion cross-section's middle node (two
///     springs of half force when that cross-section has an even number of nodes) to a node
///     at its papillary tip, with the continuous bilinear, tension-only law as a force-elongation
///     curve that accounts for the rest length (end-diastolic length x factor);
///   - clips as tension-only linear springs (FEBio has no clip phase: their rest length is the
///     target from the start);
///   - the annulus nodes and papillary tips as prescribed displacements, one load curve per
///     node and axis, sampled from the same C1 interpolation of the image frames;
///   - the follower pressure on the ventricular surface (tri6 / tri3 facets) with the same
///     smoothstep profile;
///   - leaflet contact as a sliding-elastic contact between the anterior and the posterior
///     leaflet's surfaces, friction as in the options.
/// Units are mvtwin's (mm, s, N, MPa, t). What FEBio cannot express is said in the file's
/// header comment: Rayleigh damping (the analysis is quasi-static), self-contact within one
/// leaflet, the contact wall law and the inversion guard. `comment` (provenance) is written at
/// the top. Written atomically; throws mvtwin::Error if it cannot be written.
/// The force-elongation curve of a tension-only spring for FEBio's "nonlinear spring" (measure
/// "elongation", extrapolated linearly): elongation DL from the reference length `initial`
/// (mm) against force (N), so that a spring of rest length `rest` follows `law` (a clip: law
/// null, linear stiffness k N/mm).
std::vector<std::pair<double, double>> febio_spring_curve(double initial, double rest,
                                                          const ChordaLaw* law, double k);

void write_febio(const std::filesystem::path& path, const ClosureScene& scene,
                 const ClosureOptions& options, const std::string& comment);

}  // namespace mvtwin::forward
