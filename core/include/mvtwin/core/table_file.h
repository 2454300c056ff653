#pragma once
// A study's results as an HDF5 table that h5py and pandas open: one 1-D dataset per column
// (numbers with their units, or strings), all of one length, under /table, with the format
// tag and the provenance as root attributes.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace mvtwin {

struct TableColumn {
  std::string name;                  ///< dataset name under /table
  std::string units;                 ///< "" for strings and plain counts
  std::vector<double> numbers;       ///< a numeric column (NaN for a missing value)
  std::vector<std::string> strings;  ///< or a string column (numbers empty)
  bool is_strings() const { return numbers.empty() && !strings.empty(); }
  std::size_t size() const { return is_strings() ? strings.size() : numbers.size(); }
};

struct TableFile {
  std::string format;  ///< e.g. "mvtwin-cohort-study"
  /// Root attributes (mvtwin_version, command, seed, created_utc, synthetic, ...).
  std::vector<std::pair<std::string, std::string>> attributes;
  std::vector<TableColumn> columns;
};

/// Writes atomically. Throws mvtwin::Error for columns of different lengths or an unusable path.
void write_table_file(const std::filesystem::path& path, const TableFile& table);
/// Throws mvtwin::Error naming the file when it is not a table file of mvtwin.
TableFile read_table_file(const std::filesystem::path& path);

}  // namespace mvtwin
