#include "mvtwin/studies/study_folder.h"

#include <algorithm>
#include <fstream>
#include <mutex>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"

namespace mvtwin::studies {

std::mutex& hdf5_mutex() {
  static std::mutex m;
  return m;
}

void write_json(const std::filesystem::path& path, const nlohmann::json& j) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp);
    f << j.dump(1) << "\n";
    f.close();
    if (!f) throw Error(path.string() + ": write failed");
  });
}

StudyFolder::StudyFolder(std::filesystem::path dir, std::string kind, nlohmann::json config,
                         bool write_config)
    : dir_(std::move(dir)), kind_(std::move(kind)), config_(std::move(config)) {
  create_output_directory(dir_ / "records");
  const auto cfg = dir_ / "study_config.json";
  nlohmann::json expected{{"study", kind_}, {"config", config_}};
  if (std::filesystem::exists(cfg)) {
    nlohmann::json old;
    try {
      std::ifstream f(cfg);
      old = nlohmann::json::parse(f);
    } catch (const std::exception& e) {
      throw Error(cfg.string() + ": unreadable (" + e.what() +
                  "); remove the folder or choose another --out");
    }
    if (old.value("study", "") != kind_)
      throw Error(dir_.string() + ": holds a '" + old.value("study", "?") + "' study, not '" +
                  kind_ + "'; choose another --out");
    if (old["config"] != config_) {
      std::string diff;
      for (const auto& [k, v] : config_.items())
        if (!old["config"].contains(k) || old["config"][k] != v)
          diff += (diff.empty() ? "" : ", ") + k;
      for (const auto& [k, v] : old["config"].items())
        if (!config_.contains(k)) diff += (diff.empty() ? "" : ", ") + k;
      throw Error(dir_.string() + ": holds this study with other settings (" + diff +
                  "); its results would not be this run's. Choose another --out, or remove it");
    }
    return;
  }
  if (write_config) write_json(cfg, expected);
}

std::optional<nlohmann::json> StudyFolder::record(const std::string& name) const {
  const auto p = dir_ / "records" / (name + ".json");
  if (!std::filesystem::exists(p)) return std::nullopt;
  try {
    std::ifstream f(p);
    return nlohmann::json::parse(f);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

void StudyFolder::save_record(const std::string& name, const nlohmann::json& r) const {
  write_json(dir_ / "records" / (name + ".json"), r);
}

std::unique_ptr<StudyFolder> open_study_folder(WorkPool& pool, const std::filesystem::path& dir,
                                               const std::string& kind,
                                               const nlohmann::json& config) {
  std::unique_ptr<StudyFolder> folder;
  if (pool.is_root()) folder = std::make_unique<StudyFolder>(dir, kind, config, true);
  pool.barrier();
  if (!pool.is_root()) folder = std::make_unique<StudyFolder>(dir, kind, config, false);
  return folder;
}

std::vector<std::filesystem::path> patient_files(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> files;
  for (const auto& f : std::filesystem::directory_iterator(folder))
    if (f.is_regular_file() && f.path().extension() == ".h5") files.push_back(f.path());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw Error(folder.string() + ": no patient files (*.h5)");
  return files;
}

}  // namespace mvtwin::studies
