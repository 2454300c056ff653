#include "mvtwin/detection/segmentation_labels.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

#include "mvtwin/core/error.h"

namespace mvtwin::detection {

bool SegmentationLabels::is_valid(std::string* error) const {
  if (anterior <= 0 || posterior <= 0) {
    *error = "the anterior and posterior leaflet labels must be positive (0 is the background)";
    return false;
  }
  if (annulus < 0 || papillary < 0) {
    *error = "label values cannot be negative (0 means: not labelled)";
    return false;
  }
  const int v[4] = {anterior, posterior, annulus, papillary};
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      if (v[i] != 0 && v[i] == v[j]) {
        *error = "two structures share the label value " + std::to_string(v[i]);
        return false;
      }
    }
  }
  return true;
}

std::string SegmentationLabels::describe() const {
  std::string s =
      "anterior=" + std::to_string(anterior) + " posterior=" + std::to_string(posterior);
  s += annulus ? " annulus=" + std::to_string(annulus) : " annulus=none";
  if (papillary) s += " papillary=" + std::to_string(papillary);
  return s + " (" + convention + ")";
}

SegmentationLabels segmentation_labels(std::string_view convention) {
  SegmentationLabels l;
  if (convention == "mvtool") {
    l = {2, 3, 1, 0, "mvtool"};
  } else if (convention == "mvseg") {
    l = {2, 1, 0, 0, "mvseg"};
  } else {
    std::string names;
    for (const auto& n : segmentation_convention_names()) names += (names.empty() ? "" : ", ") + n;
    throw Error("unknown label convention '" + std::string(convention) + "' (known: " + names +
                "; or give the values with --labels)");
  }
  return l;
}

std::vector<std::string> segmentation_convention_names() { return {"mvtool", "mvseg"}; }

std::string segment_role(std::string_view segment_name) {
  std::string s;
  for (char c : segment_name) {
    if (std::isalnum(static_cast<unsigned char>(c)))
      s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  auto has = [&](const char* w) { return s.find(w) != std::string::npos; };
  if (has("papillary") || s == "pm" || s == "ppm" || s == "apm" || s == "pms") return "papillary";
  if (has("annulus") || has("annular") || s == "ma" || s == "ring") return "annulus";
  if (has("anterior") || s == "aml" || s == "al" || s == "aleaflet" || s == "antleaflet")
    return "anterior";
  if (has("posterior") || s == "pml" || s == "pl" || s == "pleaflet" || s == "postleaflet")
    return "posterior";
  return "";
}

bool is_slicer_segmentation(const std::map<std::string, std::string>& fields) {
  return fields.count("Segment0_LabelValue") || fields.count("Segment0_Name");
}

NamedSegmentation slicer_segmentation(const std::vector<ImageVolume>& layers,
                                      const std::map<std::string, std::string>& fields,
                                      const std::string& source) {
  if (layers.empty()) throw Error(source + ": the segmentation holds no volume");
  auto integer = [&](const std::string& key, int fallback) {
    const auto it = fields.find(key);
    if (it == fields.end()) return fallback;
    char* e = nullptr;
    const long v = std::strtol(it->second.c_str(), &e, 10);
    if (e == it->second.c_str() || *e != '\0' || v < 0 || v > 1000000)
      throw Error(source + ": " + key + " is not a valid number ('" + it->second + "')");
    return static_cast<int>(v);
  };
  std::map<std::string, std::pair<int, int>> role;  // role -> (layer, label value)
  std::string names;
  for (int s = 0; fields.count("Segment" + std::to_string(s) + "_Name") ||
                  fields.count("Segment" + std::to_string(s) + "_LabelValue");
       ++s) {
    const std::string k = "Segment" + std::to_string(s) + "_";
    const auto nm_it = fields.find(k + "Name");
    const std::string nm = nm_it == fields.end() ? "" : nm_it->second;
    const int value = integer(k + "LabelValue", s + 1);
    const int layer = integer(k + "Layer", 0);
    names += (names.empty() ? "'" : ", '") + nm + "'";
    const std::string r = segment_role(nm);
    if (r.empty()) continue;
    if (role.count(r))
      throw Error(source + ": two segments are the " + r + " (" + names + "); give --labels");
    if (layer >= static_cast<int>(layers.size()))
      throw Error(source + ": segment '" + nm + "' is on layer " + std::to_string(layer) + " of " +
                  std::to_string(layers.size()));
    role[r] = {layer, value};
  }
  if (!role.count("anterior") || !role.count("posterior")) {
    throw Error(
        source + ": the segment names (" + (names.empty() ? std::string("none") : names) +
        ") name no anterior and posterior leaflet; rename them (e.g. 'anterior leaflet') or "
        "give --labels");
  }
  NamedSegmentation out;
  out.label_map = layers.front();
  std::fill(out.label_map.data.begin(), out.label_map.data.end(), 0.0f);
  const std::map<std::string, float> code = {
      {"annulus", 1.f}, {"anterior", 2.f}, {"posterior", 3.f}, {"papillary", 4.f}};
  for (const auto& [r, lv] : role) {
    const auto& src = layers[static_cast<size_t>(lv.first)].data;
    for (size_t v = 0; v < src.size(); ++v)
      if (std::lround(src[v]) == lv.second) out.label_map.data[v] = code.at(r);
  }
  out.labels = {2, 3, role.count("annulus") ? 1 : 0, role.count("papillary") ? 4 : 0,
                "segment names"};
  return out;
}

}  // namespace mvtwin::detection
