#pragma once
// mvtwin train-detector and mvtwin detect: the valve detector of synthetic or real TEE.
#include <cstdint>
#include <string>
#include <vector>

#include "command.h"
#include "mvtwin/detection/tee_renderer.h"
#include "mvtwin/detection/valve_detector.h"
#include "mvtwin/studies/virtual_tee.h"

namespace mvtwin::tools {

struct TrainDetectorArgs : CommandArgs {
  std::string cohort;
  std::string out;
  bool force = false;
  int n_virtual = 0;
  unsigned cohort_seed = 3030;
  int jobs = 2;
  std::string cache;
  detection::TeeRenderOptions render;
  detection::DetectorOptions detector;
  std::vector<double> train_noise = studies::kTrainingNoise;
  std::vector<std::string> truth_sets;
};

int run_train_detector(const TrainDetectorArgs& args);

struct DetectArgs : CommandArgs {
  std::string file;
  std::string model;
  std::string out;
  bool force = false;
  std::string json_path;
};

int run_detect(const DetectArgs& args);

/// Registers both commands.
void register_detect(CLI::App& app, Context& ctx);

}  // namespace mvtwin::tools
