#pragma once
// A study's output folder: what decides its numbers (study_config.json) and one record per
// finished piece of work (records/NAME.json), each written atomically, so that a killed study
// resumes without redoing anything it finished.
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {

class StudyFolder {
 public:
  /// Opens or creates `dir` for a study of `kind` whose numbers depend on `config`. With
  /// `write_config` (one process: the MPI root) a new folder gets its study_config.json; every
  /// process checks an existing one. Throws mvtwin::Error when the folder holds another kind
  /// of study or one configured otherwise (naming the keys that differ): its records would
  /// not be this study's.
  StudyFolder(std::filesystem::path dir, std::string kind, nlohmann::json config,
              bool write_config);

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path path(const std::string& file) const { return dir_ / file; }
  const nlohmann::json& config() const { return config_; }

  /// The record `name`, or nothing when absent (or unreadable: it is then made again).
  std::optional<nlohmann::json> record(const std::string& name) const;
  void save_record(const std::string& name, const nlohmann::json& record) const;

 private:
  std::filesystem::path dir_;
  std::string kind_;
  nlohmann::json config_;
};

/// The study folder on every process of `pool`: the root opens (or creates) it first, with its
/// study_config.json, then the others check it. Throws as StudyFolder does.
std::unique_ptr<StudyFolder> open_study_folder(WorkPool& pool, const std::filesystem::path& dir,
                                               const std::string& kind,
                                               const nlohmann::json& config);

/// Every patient file (*.h5) of `folder`, in name order. Throws mvtwin::Error naming the
/// folder when it holds none.
std::vector<std::filesystem::path> patient_files(const std::filesystem::path& folder);

/// One mutex for every HDF5 call a study makes from its threads (Debian's HDF5 is not built
/// thread-safe).
std::mutex& hdf5_mutex();

/// Progress of a study, for the command to show: stage, items done of total, a line of text.
struct StudyEvent {
  std::string stage;
  int done = 0, total = 0;
  std::string message;
};
using StudyProgress = std::function<void(const StudyEvent&)>;

/// Writes `j` as indented JSON, atomically.
void write_json(const std::filesystem::path& path, const nlohmann::json& j);

}  // namespace mvtwin::studies
