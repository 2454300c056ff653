#include "mvtwin/core/markups.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "raw_voxels.h"

namespace mvtwin {
namespace {

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// Sign flips from the named system to RAS.
Eigen::Vector3d to_ras(const std::string& system, const std::string& what) {
  const std::string s = upper(raw::trim(system));
  if (s == "RAS" || s == "0") return {1, 1, 1};
  if (s == "LPS" || s == "1") return {-1, -1, 1};
  throw Error(what + ": markups in coordinate system '" + system +
              "': only RAS and LPS (3D Slicer's world spaces) are understood");
}

bool ends_with(const std::string& s, const std::string& e) {
  return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

}  // namespace

MarkupList read_markups(const std::filesystem::path& path) {
  const std::string what = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(what + ": cannot open the markups file");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  MarkupList out;
  std::string lname = what;
  std::transform(lname.begin(), lname.end(), lname.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ends_with(lname, ".fcsv")) {
    out.coordinate_system = "RAS";
    std::istringstream ls(text);
    std::string line;
    std::vector<std::string> columns = {"id", "x", "y", "z"};
    int row = 0;
    while (std::getline(ls, line)) {
      line = raw::trim(line);
      if (line.empty()) continue;
      if (line[0] == '#') {
        const auto eq = line.find('=');
        if (eq == std::string::npos) continue;
        std::string key = raw::trim(line.substr(1, eq - 1));
        const std::string value = raw::trim(line.substr(eq + 1));
        std::transform(key.begin(), key.end(), key.begin(),
                       [](unsigned char c) { return std::tolower(c); });
        if (key == "coordinatesystem") {
          to_ras(value, what);
          out.coordinate_system = upper(value) == "0"   ? "RAS"
                                  : upper(value) == "1" ? "LPS"
                                                        : upper(value);
        }
        if (key == "columns") {
          columns.clear();
          std::istringstream cs(value);
          std::string c;
          while (std::getline(cs, c, ',')) columns.push_back(raw::trim(c));
        }
        continue;
      }
      ++row;
      std::vector<std::string> cells;
      std::istringstream cs(line);
      std::string c;
      while (std::getline(cs, c, ',')) cells.push_back(raw::trim(c));
      auto col = [&](const std::string& name) -> int {
        const auto it = std::find(columns.begin(), columns.end(), name);
        return it == columns.end() ? -1 : static_cast<int>(it - columns.begin());
      };
      const int cx = col("x"), cy = col("y"), cz = col("z"), cl = col("label");
      if (cx < 0 || cy < 0 || cz < 0) throw Error(what + ": the columns header has no x, y, z");
      if (static_cast<int>(cells.size()) <= std::max({cx, cy, cz}))
        throw Error(what + ": row " + std::to_string(row) + " has " + std::to_string(cells.size()) +
                    " cells");
      MarkupPoint p;
      for (int k = 0; k < 3; ++k) {
        const std::string& cell = cells[static_cast<size_t>(k == 0 ? cx : k == 1 ? cy : cz)];
        char* end = nullptr;
        p.position[k] = std::strtod(cell.c_str(), &end);
        if (end == cell.c_str() || *end != '\0')
          throw Error(what + ": row " + std::to_string(row) + ": '" + cell + "' is not a number");
      }
      p.label =
          cl >= 0 && cl < static_cast<int>(cells.size()) ? cells[static_cast<size_t>(cl)] : "";
      out.points.push_back(p);
    }
  } else {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(text);
    } catch (const std::exception& e) {
      throw Error(what + ": not a valid markups JSON file (" + std::string(e.what()) + ")");
    }
    if (!j.is_object() || !j.contains("markups") || !j["markups"].is_array())
      throw Error(what + ": not a 3D Slicer markups file (no \"markups\" list)");
    for (const auto& m : j["markups"]) {
      if (!m.is_object()) throw Error(what + ": a markups entry is not an object");
      const std::string system = m.contains("coordinateSystem") && m["coordinateSystem"].is_string()
                                     ? m["coordinateSystem"].get<std::string>()
                                     : "LPS";
      to_ras(system, what);
      if (out.coordinate_system.empty()) out.coordinate_system = upper(system);
      if (!m.contains("controlPoints")) continue;
      if (!m["controlPoints"].is_array()) throw Error(what + ": \"controlPoints\" is not a list");
      for (const auto& c : m["controlPoints"]) {
        MarkupPoint p;
        p.label =
            c.contains("label") && c["label"].is_string() ? c["label"].get<std::string>() : "";
        const std::string status = c.contains("positionStatus") && c["positionStatus"].is_string()
                                       ? c["positionStatus"].get<std::string>()
                                       : "defined";
        if (status != "defined" && status != "preview") {
          out.skipped.push_back(p.label);
          continue;
        }
        if (!c.contains("position") || !c["position"].is_array() || c["position"].size() != 3)
          throw Error(what + ": control point '" + p.label + "' has no 3-component position");
        for (int k = 0; k < 3; ++k) {
          if (!c["position"][static_cast<size_t>(k)].is_number())
            throw Error(what + ": control point '" + p.label + "' has a non-numeric position");
          p.position[k] = c["position"][static_cast<size_t>(k)].get<double>();
        }
        p.position = p.position.cwiseProduct(to_ras(system, what));
        out.points.push_back(p);
      }
    }
  }
  if (out.coordinate_system == "LPS" && ends_with(lname, ".fcsv")) {
    for (auto& p : out.points) p.position = p.position.cwiseProduct(Eigen::Vector3d(-1, -1, 1));
  }
  for (const auto& p : out.points) {
    if (!p.position.allFinite())
      throw Error(what + ": control point '" + p.label + "' has a NaN/Inf coordinate");
  }
  if (out.points.empty()) throw Error(what + ": the markups file holds no defined control points");
  return out;
}

void write_markups_json(const std::filesystem::path& path, const std::vector<MarkupPoint>& points) {
  nlohmann::json cps = nlohmann::json::array();
  int id = 1;
  for (const auto& p : points) {
    cps.push_back({{"id", std::to_string(id++)},
                   {"label", p.label},
                   {"description", ""},
                   {"associatedNodeID", ""},
                   {"position", {-p.position.x(), -p.position.y(), p.position.z()}},
                   {"orientation", {-1.0, -0.0, -0.0, -0.0, -1.0, -0.0, 0.0, 0.0, 1.0}},
                   {"selected", true},
                   {"locked", false},
                   {"visibility", true},
                   {"positionStatus", "defined"}});
  }
  nlohmann::json j = {{"@schema",
                       "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/"
                       "Markups/Resources/Schema/markups-schema-v1.0.3.json#"},
                      {"markups",
                       {{{"type", "Fiducial"},
                         {"coordinateSystem", "LPS"},
                         {"coordinateUnits", "mm"},
                         {"locked", false},
                         {"fixedNumberOfControlPoints", false},
                         {"labelFormat", "%N-%d"},
                         {"lastUsedControlPointNumber", points.size()},
                         {"controlPoints", cps}}}}};
  const std::string text = j.dump(4);
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text << "\n";
    f.close();
    if (!f) throw Error(path.string() + ": write failed (disk full?)");
  });
}

}  // namespace mvtwin
