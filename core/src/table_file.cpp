#include "mvtwin/core/table_file.h"

#include "hdf5_io.h"
#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"

namespace mvtwin {

void write_table_file(const std::filesystem::path& path, const TableFile& t) {
  if (t.format.empty()) throw Error(path.string() + ": a table file needs a format tag");
  std::size_t rows = t.columns.empty() ? 0 : t.columns.front().size();
  std::vector<std::string> names, kinds, units, attribute_names;
  for (const TableColumn& c : t.columns) {
    if (c.name.empty() || c.name.find('/') != std::string::npos)
      throw Error(path.string() + ": bad column name '" + c.name + "'");
    if (c.size() != rows)
      throw Error(path.string() + ": column '" + c.name + "' has " + std::to_string(c.size()) +
                  " rows, the first has " + std::to_string(rows));
    names.push_back(c.name);
    kinds.push_back(c.is_strings() || rows == 0 ? "string" : "number");
    units.push_back(c.units);
  }
  for (const auto& [k, v] : t.attributes) attribute_names.push_back(k);
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    h5::Location root = h5::Location::create_file(tmp);
    root.attr("format", t.format);
    root.attr("rows", static_cast<long>(rows));
    for (const auto& [k, v] : t.attributes) root.attr(k, v);
    root.write_strings("column_names", names);
    root.write_strings("column_kinds", kinds);
    root.write_strings("column_units", units);
    root.write_strings("attribute_names", attribute_names);
    const h5::Location table = root.create_group("table", true);
    for (const TableColumn& c : t.columns) {
      if (c.is_strings() || rows == 0) {
        table.write_strings(c.name, c.strings);
      } else {
        table.write(c.name, c.numbers, {static_cast<hsize_t>(rows)},
                    c.units.empty() ? nullptr : c.units.c_str());
      }
    }
  });
}

TableFile read_table_file(const std::filesystem::path& path) {
  const h5::Location root = h5::Location::open_file(path);
  if (!root.has_attr("format") || !root.exists("table"))
    throw Error(path.string() + ": not an mvtwin table file (no format tag or /table)");
  TableFile t;
  t.format = root.attr_string("format");
  for (const std::string& k : root.read_strings("attribute_names"))
    t.attributes.emplace_back(k, root.attr_string(k));
  const h5::Location table = root.open_group("table");
  const std::vector<std::string> names = root.read_strings("column_names");
  const std::vector<std::string> kinds = root.read_strings("column_kinds");
  const std::vector<std::string> units = root.read_strings("column_units");
  if (kinds.size() != names.size() || units.size() != names.size())
    throw Error(path.string() + ": column_names, column_kinds and column_units differ in length");
  const long rows = root.attr_long("rows");
  for (std::size_t i = 0; i < names.size(); ++i) {
    TableColumn c;
    c.name = names[i];
    c.units = units[i];
    if (kinds[i] == "number") {
      std::vector<hsize_t> dims;
      c.numbers = table.read_doubles(c.name, &dims, {rows}, "(rows)");
    } else {
      c.strings = table.read_strings(c.name);
      if (static_cast<long>(c.strings.size()) != rows)
        throw Error(path.string() + ": column '" + c.name + "' has the wrong length");
    }
    t.columns.push_back(std::move(c));
  }
  return t;
}

}  // namespace mvtwin
