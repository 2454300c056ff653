#pragma once
// Valve anatomy from 3D(+t) TEE, coarse to fine in the spirit of Marginal Space Learning
// (Mansi et al. 2012, Sec. 2.1): the valve's position, then the landmarks around it, then the
// LA surface (a shape model placed by the landmarks, refined along its normals by a learned
// boundary detector and kept in the shape space), then tracking over the frames. The learned
// detectors are OpenCV random forests on 3D Haar-like features (integral_volume.h).
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mvtwin/core/image_volume.h"
#include "mvtwin/core/valve_sequence.h"
#include "mvtwin/detection/shape_model.h"

namespace mvtwin::detection {

struct DetectorOptions {
  std::vector<int> scales = {1, 3, 6, 12};  ///< box half-widths of the features, voxels
  int trees = 40;
  int max_depth = 14;
  int samples_per_volume = 1500;   ///< training samples per volume and detector
  double position_step_mm = 2.0;   ///< grid of the position search
  double landmark_search_mm = 12;  ///< half-width of each landmark's search box
  double track_search_mm = 6;      ///< the same when tracking from the previous frame
  double normal_search_mm = 4;     ///< along the surface normals
  int surface_iterations = 3;
  std::uint64_t seed = 1;
  std::string invalid() const;
};

/// One training example: a volume and the valve in it (landmarks, papillary tips, LA surface).
struct TrainingVolume {
  const ImageVolume* image = nullptr;
  const ValveFrame* truth = nullptr;
};

/// What detect() reports besides the valve.
struct DetectionInfo {
  Eigen::Vector3d centre;  ///< centre of the detected annulus, mm
  double seconds = 0;
};

/// The frame with its unobserved leaflet tips (closing and closed frames) taken from its LA
/// surface, as the open frames define them: the middle of each leaflet's free edge (s = 0.25
/// anterior, 0.75 posterior, at the free edge). Frames without a surface are returned as they are.
ValveFrame with_surface_tips(const ValveFrame& frame);

class ValveDetector {
 public:
  ValveDetector();
  ~ValveDetector();
  ValveDetector(ValveDetector&&) noexcept;
  ValveDetector& operator=(ValveDetector&&) noexcept;

  /// Trains every stage. Throws mvtwin::Error for invalid options or too few usable volumes
  /// (each needs observed landmarks and an LA surface). `progress` receives stage names.
  static ValveDetector train(const std::vector<TrainingVolume>& data,
                             const DetectorOptions& options,
                             const std::function<void(const std::string&)>& progress = {});

  /// Detects the valve in one volume; with `previous` (the detection in the frame before),
  /// searches near it and starts the surface from it (tracking).
  ValveFrame detect(const ImageVolume& image, const ValveFrame* previous = nullptr,
                    DetectionInfo* info = nullptr) const;

  /// Every frame, tracked; landmarks and surfaces are smoothed over time (3-frame window, the
  /// ends kept). Frame times come from the volumes.
  std::vector<ValveFrame> detect_sequence(const std::vector<ImageVolume>& frames,
                                          std::vector<DetectionInfo>* info = nullptr) const;

  const ShapeModel& shape() const;
  const DetectorOptions& options() const;

  /// A single file (OpenCV FileStorage, .yml.gz) holding the options, the shape model, the
  /// forests and `provenance` (name = value lines). Written atomically.
  void save(const std::filesystem::path& path,
            const std::vector<std::pair<std::string, std::string>>& provenance) const;
  /// Throws mvtwin::Error naming the file when it is missing or not an mvtwin detector model.
  static ValveDetector load(const std::filesystem::path& path);
  /// The provenance a model file records (name = value), without loading its forests.
  static std::vector<std::pair<std::string, std::string>> provenance(
      const std::filesystem::path& path);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mvtwin::detection
