#include "mvtwin/detection/segmentation_labels.h"

#include <algorithm>
#include <cctype>

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

}  // namespace mvtwin::detection
