#pragma once
// Synthetic 3D+t transoesophageal echo (TEE) of a valve sequence: what a virtual patient's
// images would look like, for training and testing detection without patient images.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/valve_sequence.h"

namespace mvtwin::detection {

/// How the synthetic TEE is acquired. Lengths in mm, angles in degrees, levels relative to the
/// echo of a leaflet seen face on (amplitude 1).
struct TeeRenderOptions {
  double voxel_mm = 1.0;         ///< output voxel size (TEE: 0.75-1.58 mm)
  double box_mm = 90.0;          ///< edge of the output cube, centred on the annulus
  double sector_deg = 80.0;      ///< full opening of the pyramidal sector, both directions
  double probe_depth_mm = 78.0;  ///< probe (sector apex) to annulus centre
  /// Variation of the acquisition between patients (drawn from `seed`): the probe's direction
  /// tilts by up to this angle, the volume turns about the beam by up to twice it, the depth
  /// changes by up to 8 mm and the cube's centre moves by up to 6 mm from the annulus centre.
  /// 0: the standard view exactly.
  double probe_jitter_deg = 0.0;
  double axial_psf_mm = 0.35;   ///< point-spread function SD along the beam
  double lateral_psf_mm = 1.1;  ///< PSF SD across the beam at probe_depth_mm (grows with depth)
  double attenuation_db_per_mm = 0.06;  ///< after time-gain compensation, two-way
  double dynamic_range_db = 50.0;       ///< log compression: 0 dB -> 255, -range -> 0
  double speckle = 1.0;                 ///< 1: fully developed (Rayleigh) speckle; 0: none
  double noise = 0.004;                 ///< additive electronic noise SD (relative amplitude)
  double dropout_fraction = 0.08;  ///< fraction of beams with a drop-out (shadow, poor contact)
  double blood = 1.5e-4;           ///< blood backscatter (relative intensity, about -38 dB)
  std::uint64_t seed = 1;

  /// Empty when valid, else what is wrong.
  std::string invalid() const;
};

/// The probe and the volume's axes for a frame: apex, beam axis (towards the valve) and the
/// volume geometry (axes x lateral, y elevation, z along the beam).
struct TeeGeometry {
  Eigen::Vector3d apex;
  Eigen::Matrix3d axes;  ///< columns: lateral, elevation, beam axis (world, unit)
  ImageVolume grid;      ///< geometry only (no data)
};

/// The acquisition geometry, fixed over a sequence: from the end-diastolic frame's annulus
/// (the probe sits posterior to the left atrium, behind and above the valve).
TeeGeometry tee_geometry(const ValveSequence& sequence, const TeeRenderOptions& options);

/// Renders every frame (8-bit grey levels stored as float, 0-255) in that geometry: thin
/// bright leaflets (brightest face on to the beam), myocardium, aortic root, papillary
/// muscles, dark blood, Rayleigh speckle, a PSF wider across than along the beam, depth
/// attenuation, drop-outs and noise. Frames without an observed leaflet surface are rendered
/// without leaflets. Throws mvtwin::Error for invalid options or an empty sequence.
std::vector<ImageVolume> render_tee(const ValveSequence& sequence, const TeeRenderOptions& options);

/// One frame.
ImageVolume render_tee_frame(const ValveSequence& sequence, int frame, const TeeGeometry& geometry,
                             const TeeRenderOptions& options);

}  // namespace mvtwin::detection
